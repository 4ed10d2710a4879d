"""A course's overrides of the rigs' limits during its slots.

Revision ID: 0016
Revises: 0015
Create Date: 2026-11-24

``course_settings``: one row per course that overrides any limit (turn limit,
idle limit, longest run) as one JSON object, a version counting the saves,
when and by whom the last was made.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0016"
down_revision: str | None = "0015"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    op.create_table(
        "course_settings",
        sa.Column("course_id", sa.Integer(), nullable=False),
        sa.Column("values", sa.JSON(), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_by", sa.String(64), nullable=True),
        sa.ForeignKeyConstraint(
            ["course_id"],
            ["courses.id"],
            name=op.f("fk_course_settings_course_id_courses"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("course_id", name=op.f("pk_course_settings")),
    )


def downgrade() -> None:
    op.drop_table("course_settings")
