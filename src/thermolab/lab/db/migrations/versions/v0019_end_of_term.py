"""The end of a term: closed courses and draft assignments.

Revision ID: 0019
Revises: 0018
Create Date: 2026-11-28

``courses.closed_at`` and ``courses.closed_by`` (a login name, as text like
the other "by" columns, so that a teacher's removal replaces it): a course
closed at the end of its term is read and exported, never changed; null in
both is an open course, as every course was before.

``assignments.draft``: an assignment copied to the next term's course waits
there, seen by its teachers only, until one of them publishes it; every
existing assignment is published (false).
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0019"
down_revision: str | None = "0018"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    with op.batch_alter_table("courses") as batch:
        batch.add_column(sa.Column("closed_at", sa.DateTime(timezone=True), nullable=True))
        batch.add_column(sa.Column("closed_by", sa.String(64), nullable=True))
    with op.batch_alter_table("assignments") as batch:
        batch.add_column(
            sa.Column("draft", sa.Boolean(), nullable=False, server_default=sa.false())
        )
