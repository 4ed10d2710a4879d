"""LTI launch state in the database; teaching assistants in courses.

Revision ID: 0020
Revises: 0019
Create Date: 2026-11-28

``lti_handoffs``: a pending deep-linking request and a new window's ticket
(see :mod:`thermolab.lab.db.lti_models`), which lived in one process's memory
and so broke behind several web workers. Nothing is carried over: such state
lives for minutes, and a restart always dropped it.

``course_members.role`` may be ``assistant``: a teaching assistant of that
course (:mod:`thermolab.lab.accounts.policy` says what one may do).
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0020"
down_revision: str | None = "0019"
branch_labels: str | None = None
depends_on: str | None = None


def _fk(column: str, target: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        [column],
        [f"{target}.id"],
        name=op.f(f"fk_lti_handoffs_{column}_{target}"),
        ondelete="CASCADE",
    )


def upgrade() -> None:
    op.create_table(
        "lti_handoffs",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("key_hash", sa.String(64), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("platform_id", sa.Integer(), nullable=False),
        sa.Column("data", sa.JSON(), nullable=False),
        sa.Column("expires_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("kind IN ('deep_link', 'window')", name=op.f("ck_lti_handoffs_kind")),
        _fk("user_id", "users"),
        _fk("platform_id", "lti_platforms"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lti_handoffs")),
        sa.UniqueConstraint("key_hash", name=op.f("uq_lti_handoffs_key_hash")),
    )
    for column in ("user_id", "platform_id", "expires_at"):
        op.create_index(op.f(f"ix_lti_handoffs_{column}"), "lti_handoffs", [column])
    with op.batch_alter_table("course_members") as batch:
        batch.drop_constraint(op.f("ck_course_members_role"), type_="check")
        batch.create_check_constraint(
            op.f("ck_course_members_role"), "role IN ('student', 'teacher', 'assistant')"
        )
