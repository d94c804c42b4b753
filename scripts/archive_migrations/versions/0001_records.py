"""The first schema: one row per archived result.

Revision ID: 0001
Revises:
"""
from alembic import op
import sqlalchemy as sa

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade():
    op.create_table(
        "records",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("device_serial", sa.String(200), nullable=False),
        sa.Column("rig", sa.String(200), nullable=False),
        sa.Column("time", sa.DateTime, nullable=False),
        sa.Column("method", sa.String(20), nullable=False),
        sa.Column("local_gravity", sa.Float, nullable=False),
        sa.Column("model", sa.String(200), nullable=False),
        sa.Column("result_json", sa.Text, nullable=False),
        sa.Column("position_table", sa.Text, nullable=True),
        sa.Column("input_sha256", sa.String(64), nullable=False),
        sa.Column("result_sha256", sa.String(64), nullable=False),
        sa.Column("added_at", sa.DateTime, nullable=False),
        sa.Column("added_by", sa.String(200), nullable=False),
        sa.UniqueConstraint("input_sha256", "result_sha256", name="uq_records_input_result"),
    )
    op.create_index("ix_records_device_serial", "records", ["device_serial"])
    op.create_index("ix_records_rig", "records", ["rig"])


def downgrade():
    op.drop_table("records")
