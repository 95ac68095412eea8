"""Alembic environment: migrations run on the connection doorloc.recipes.store hands over.

``config.attributes["connection"]`` is an open SQLAlchemy connection; doorloc never reads an
alembic.ini. On PostgreSQL a transaction-scoped advisory lock makes two processes that open the
same database at once (e.g. two service workers) migrate one after the other.
"""

from alembic import context
from sqlalchemy import text

from doorloc.recipes.tables import Base

#: arbitrary fixed key of the advisory lock that serialises doorloc migrations on PostgreSQL
_MIGRATION_LOCK_KEY = 7_317_202_611


def run_migrations_online() -> None:
    connection = context.config.attributes["connection"]
    context.configure(connection=connection, target_metadata=Base.metadata, render_as_batch=True)
    with context.begin_transaction():
        if connection.dialect.name == "postgresql":
            connection.execute(text("SELECT pg_advisory_xact_lock(:k)"), {"k": _MIGRATION_LOCK_KEY})
        context.run_migrations()


if context.is_offline_mode():
    raise SystemExit("doorloc migrations run online only: use `doorloc recipes init-db`")
run_migrations_online()
