"""The personal API token a turn was asked for with.

Revision ID: 0021
Revises: 0020
Create Date: 2026-11-28

``queue_entries.token_id`` and ``control_sessions.token_id``: the token a
script asked for control with (passed from its queue place to its turn), so
that revoking the token ends that turn at once and the rig goes to its safe
state then, not at the client timeout. Null for a login's (the browser's)
turn, as every existing one is. No foreign key: revoking deletes the token's
row, and the turn's record keeps the number.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0021"
down_revision: str | None = "0020"
branch_labels: str | None = None
depends_on: str | None = None

_TABLES = ("queue_entries", "control_sessions")


def upgrade() -> None:
    for table in _TABLES:
        with op.batch_alter_table(table) as batch:
            batch.add_column(sa.Column("token_id", sa.Integer(), nullable=True))


def downgrade() -> None:
    for table in _TABLES:
        with op.batch_alter_table(table) as batch:
            batch.drop_column("token_id")
