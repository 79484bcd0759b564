"""Alembic's environment for the calibration database: the migrations run on the connection that
:func:`inscal.lab.opening.upgrade_database` hands over (``config.attributes["connection"]``), inside
its transaction, so an upgrade is all or nothing (SQLite and PostgreSQL both have transactional DDL)."""

from alembic import context

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=None, transactional_ddl=True)
with context.begin_transaction():
    context.run_migrations()
