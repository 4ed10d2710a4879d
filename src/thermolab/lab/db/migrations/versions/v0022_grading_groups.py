"""A teacher's grading tools: mark overrides, deadline extensions, lab groups.

Revision ID: 0022
Revises: 0021
Create Date: 2026-11-28

``grade_overrides``: a teacher's mark and comment for one student on one
assignment (the automatic mark stays on the hand-in). ``deadline_extensions``:
one student's later deadline for one assignment. ``lab_groups`` and
``lab_group_members``: students of a course who share a run and a hand-in
(at most one group per student and course). ``submissions.handed_in_by``: the
group member who handed in for the student (null for every existing hand-in,
each handed in by its student).
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0022"
down_revision: str | None = "0021"
branch_labels: str | None = None
depends_on: str | None = None


def _fk(table: str, column: str, target: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        [column], [f"{target}.id"], name=op.f(f"fk_{table}_{column}_{target}"), ondelete="CASCADE"
    )


def _per_student(table: str, *columns: sa.Column[object]) -> None:
    """A table of one row per (assignment, student), set by a teacher."""
    op.create_table(
        table,
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("assignment_id", sa.Integer(), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        *columns,
        sa.Column("set_by", sa.String(64), nullable=False),
        sa.Column("set_at", sa.DateTime(timezone=True), nullable=False),
        _fk(table, "assignment_id", "assignments"),
        _fk(table, "user_id", "users"),
        sa.PrimaryKeyConstraint("id", name=op.f(f"pk_{table}")),
        sa.UniqueConstraint(
            "assignment_id", "user_id", name=op.f(f"uq_{table}_assignment_id_user_id")
        ),
    )
    for column in ("assignment_id", "user_id"):
        op.create_index(op.f(f"ix_{table}_{column}"), table, [column])


def upgrade() -> None:
    _per_student(
        "grade_overrides",
        sa.Column("mark", sa.Float(), nullable=False),
        sa.Column("comment", sa.Text(), nullable=False),
    )
    _per_student(
        "deadline_extensions", sa.Column("deadline", sa.DateTime(timezone=True), nullable=False)
    )
    op.create_table(
        "lab_groups",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("course_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(64), nullable=False),
        sa.Column("created_by", sa.String(64), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        _fk("lab_groups", "course_id", "courses"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lab_groups")),
        sa.UniqueConstraint("course_id", "name", name=op.f("uq_lab_groups_course_id_name")),
    )
    op.create_index(op.f("ix_lab_groups_course_id"), "lab_groups", ["course_id"])
    op.create_table(
        "lab_group_members",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("group_id", sa.Integer(), nullable=False),
        sa.Column("course_id", sa.Integer(), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        _fk("lab_group_members", "group_id", "lab_groups"),
        _fk("lab_group_members", "course_id", "courses"),
        _fk("lab_group_members", "user_id", "users"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lab_group_members")),
        sa.UniqueConstraint(
            "course_id", "user_id", name=op.f("uq_lab_group_members_course_id_user_id")
        ),
    )
    for column in ("group_id", "user_id"):
        op.create_index(op.f(f"ix_lab_group_members_{column}"), "lab_group_members", [column])
    with op.batch_alter_table("submissions") as batch:
        batch.add_column(sa.Column("handed_in_by", sa.String(64), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("submissions") as batch:
        batch.drop_column("handed_in_by")
    for table in ("lab_group_members", "lab_groups", "deadline_extensions", "grade_overrides"):
        op.drop_table(table)
