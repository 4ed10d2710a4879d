"""Teacher settings per rig, stored in the database.

Revision ID: 0010
Revises: 0009
Create Date: 2026-11-24

``rig_settings``: one row per rig, the teacher settings as one JSON object
(names from ``thermolab.lab.config.teacher_settings``), a version counting the
saves, when and by whom the last was made. Rows are written at start-up from
the lab's file when missing (the first values), then by teachers.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0010"
down_revision: str | None = "0009"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    op.create_table(
        "rig_settings",
        sa.Column("rig_id", sa.String(64), nullable=False),
        sa.Column("values", sa.JSON(), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_by", sa.String(64), nullable=True),
        sa.PrimaryKeyConstraint("rig_id", name=op.f("pk_rig_settings")),
    )


def downgrade() -> None:
    op.drop_table("rig_settings")
