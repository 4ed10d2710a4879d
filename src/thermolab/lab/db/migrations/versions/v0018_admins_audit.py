"""Lab administrators and the audit log.

Revision ID: 0018
Revises: 0017
Create Date: 2026-11-28

``users.admin``: a lab administrator (a teacher who also manages accounts,
rigs, LTI platforms and reads the audit log). So that a lab keeps an
administrator, the oldest teacher account (the one ``thermolab user add``
made at installation) becomes one; every other teacher acts in their own
courses only from now on (``thermolab user admin NAME`` promotes more).

``audit_log``: one row per privileged action (who, what, on what, when,
from where, a JSON detail).
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0018"
down_revision: str | None = "0017"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    with op.batch_alter_table("users") as batch:
        batch.add_column(
            sa.Column("admin", sa.Boolean(), nullable=False, server_default=sa.false())
        )
    users = sa.table(
        "users",
        sa.column("id", sa.Integer()),
        sa.column("role", sa.String()),
        sa.column("created_at", sa.DateTime()),
        sa.column("admin", sa.Boolean()),
    )
    first = op.get_bind().scalar(
        sa.select(users.c.id)
        .where(users.c.role == "teacher")
        .order_by(users.c.created_at, users.c.id)
        .limit(1)
    )
    if first is not None:
        op.execute(users.update().where(users.c.id == first).values(admin=True))
    op.create_table(
        "audit_log",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("actor", sa.String(64), nullable=False),
        sa.Column("action", sa.String(48), nullable=False),
        sa.Column("target", sa.String(200), nullable=False),
        sa.Column("address", sa.String(64), nullable=True),
        sa.Column("detail", sa.JSON(), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_audit_log")),
    )
    op.create_index(op.f("ix_audit_log_at"), "audit_log", ["at"])
    op.create_index(op.f("ix_audit_log_action"), "audit_log", ["action"])


def downgrade() -> None:
    op.drop_index(op.f("ix_audit_log_action"), table_name="audit_log")
    op.drop_index(op.f("ix_audit_log_at"), table_name="audit_log")
    op.drop_table("audit_log")
    with op.batch_alter_table("users") as batch:
        batch.drop_column("admin")
