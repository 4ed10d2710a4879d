"""Courses with their teachers and students, the rigs per course, forced password change.

Revision ID: 0009
Revises: 0007
Create Date: 2026-11-24

``courses`` (name, title, enrolment code), ``course_members`` (a user once
per course, as teacher or student), ``course_rigs`` (the rigs a course's
students may use; none listed means all) and ``users.must_change_password``
(set by a teacher's reset: a temporary password must be replaced first).
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0009"
down_revision: str | None = "0008"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    with op.batch_alter_table("users") as batch:
        batch.add_column(
            sa.Column(
                "must_change_password", sa.Boolean(), nullable=False, server_default=sa.false()
            )
        )
    op.create_table(
        "courses",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("name", sa.String(64), nullable=False),
        sa.Column("title", sa.String(200), nullable=False),
        sa.Column("enrol_code", sa.String(32), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_courses")),
        sa.UniqueConstraint("name", name=op.f("uq_courses_name")),
        sa.UniqueConstraint("enrol_code", name=op.f("uq_courses_enrol_code")),
    )
    op.create_table(
        "course_members",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("course_id", sa.Integer(), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("role", sa.String(16), nullable=False),
        sa.Column("joined_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("role IN ('student', 'teacher')", name=op.f("ck_course_members_role")),
        sa.ForeignKeyConstraint(
            ["course_id"],
            ["courses.id"],
            name=op.f("fk_course_members_course_id_courses"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["user_id"],
            ["users.id"],
            name=op.f("fk_course_members_user_id_users"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_course_members")),
        sa.UniqueConstraint(
            "course_id", "user_id", name=op.f("uq_course_members_course_id_user_id")
        ),
    )
    op.create_index(
        op.f("ix_course_members_course_id"), "course_members", ["course_id"], unique=False
    )
    op.create_index(op.f("ix_course_members_user_id"), "course_members", ["user_id"], unique=False)
    op.create_table(
        "course_rigs",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("course_id", sa.Integer(), nullable=False),
        sa.Column("rig_id", sa.String(64), nullable=False),
        sa.ForeignKeyConstraint(
            ["course_id"],
            ["courses.id"],
            name=op.f("fk_course_rigs_course_id_courses"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_course_rigs")),
        sa.UniqueConstraint("course_id", "rig_id", name=op.f("uq_course_rigs_course_id_rig_id")),
    )
    op.create_index(op.f("ix_course_rigs_course_id"), "course_rigs", ["course_id"], unique=False)


def downgrade() -> None:
    op.drop_index(op.f("ix_course_rigs_course_id"), table_name="course_rigs")
    op.drop_table("course_rigs")
    op.drop_index(op.f("ix_course_members_user_id"), table_name="course_members")
    op.drop_index(op.f("ix_course_members_course_id"), table_name="course_members")
    op.drop_table("course_members")
    op.drop_table("courses")
    with op.batch_alter_table("users") as batch:
        batch.drop_column("must_change_password")
