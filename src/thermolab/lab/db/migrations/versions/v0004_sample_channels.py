"""Samples keep every channel of the run: the runner's timing, and a rig's extra channels.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-24

``t_read``, ``jitter`` and ``lateness`` (:data:`thermolab.records.RUN_CHANNELS`)
become columns; ``extra`` holds the channels a rig or controller adds, by name
(JSON). Samples stored earlier never had them: they stay null, and their
export has the columns ``t,u,y,k`` as before.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | None = None
depends_on: str | None = None

_TIMING = ("t_read", "jitter", "lateness")


def upgrade() -> None:
    # Only the missing columns: a database stamped back to an older revision (as the
    # migration tests do) may already have them.
    present = {c["name"] for c in sa.inspect(op.get_bind()).get_columns("samples")}
    new = [sa.Column(name, sa.Float(), nullable=True) for name in _TIMING]
    new.append(sa.Column("extra", sa.JSON(), nullable=True))
    # batch mode: SQLite rebuilds the table, PostgreSQL adds the columns in place.
    with op.batch_alter_table("samples") as batch:
        for column in new:
            if column.name not in present:
                batch.add_column(column)


def downgrade() -> None:
    with op.batch_alter_table("samples") as batch:
        batch.drop_column("extra")
        for name in reversed(_TIMING):
            batch.drop_column(name)
