"""Alembic environment: migrations run on the connection the lab hands over.

:meth:`thermolab.lab.db.Database.upgrade` builds the Alembic configuration in
code and passes an open connection in ``config.attributes["connection"]``;
there is no ``alembic.ini`` and no URL here. To write a new migration, see
``docs/contributing.md`` ("Changing the database schema").
"""

from __future__ import annotations

from alembic import context
from sqlalchemy import Connection

from thermolab.lab.db.models import Base


def _run_migrations() -> None:
    connection = context.config.attributes.get("connection")
    if not isinstance(connection, Connection):
        raise RuntimeError(
            "the lab's migrations run through thermolab.lab.db.Database.upgrade(), "
            "which passes an open connection"
        )
    context.configure(
        connection=connection,
        target_metadata=Base.metadata,
        # SQLite alters tables by copying them; batch mode does that for us.
        render_as_batch=connection.dialect.name == "sqlite",
        compare_type=True,
    )
    with context.begin_transaction():
        context.run_migrations()


# Alembic executes this file inside an active migration context; importing it
# anywhere else (test collection, documentation tools) must do nothing.
if hasattr(context, "config"):
    _run_migrations()
