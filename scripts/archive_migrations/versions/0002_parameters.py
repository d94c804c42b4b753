"""The nine intrinsic parameters of each record with their expanded uncertainties, as rows
(history and control charts query them without parsing every result), filled in for the records
of revision 0001.

Revision ID: 0002
Revises: 0001
"""
import json

from alembic import op
import sqlalchemy as sa

import accel_archive

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade():
    parameters = op.create_table(
        "parameters",
        sa.Column("record_id", sa.Integer, sa.ForeignKey("records.id", ondelete="CASCADE"),
                  primary_key=True),
        sa.Column("name", sa.String(40), primary_key=True),
        sa.Column("value", sa.Float, nullable=False),
        sa.Column("expanded", sa.Float, nullable=False),
        sa.Column("k", sa.Float, nullable=False),
    )
    connection = op.get_bind()
    rows = connection.execute(sa.text("SELECT id, result_json FROM records")).fetchall()
    for record_id, result_json in rows:
        values = accel_archive.parameter_values(json.loads(result_json),
                                                "archive record %d" % record_id)
        connection.execute(parameters.insert(), [
            {"record_id": record_id, "name": name, "value": v, "expanded": U, "k": k}
            for name, (v, U, k) in values.items()])


def downgrade():
    op.drop_table("parameters")
