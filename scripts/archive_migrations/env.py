"""Alembic environment of the lab archive: always run by accel_archive.upgrade() on a
connection it opened (and locked) itself, inside its transaction."""
import os
import sys

from alembic import context

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.realpath(__file__))))

connection = context.config.attributes.get("connection")
if connection is None:
    raise RuntimeError("the archive schema is upgraded through accel_archive.upgrade(), "
                       "not the alembic command line")
context.configure(connection=connection, transactional_ddl=True)
with context.begin_transaction():
    context.run_migrations()
