"""Pictures of the guide pages, stored in the database.

Revision ID: 0017
Revises: 0016
Create Date: 2026-11-24

``guide_images``: one row per picture a teacher uploaded for a rig's guide,
re-encoded without metadata: its bytes, content type, size, width, height,
SHA-256 (unique per rig: the same picture is stored once), who uploaded it
and when.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0017"
down_revision: str | None = "0016"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    op.create_table(
        "guide_images",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("rig_id", sa.String(64), nullable=False),
        sa.Column("content_type", sa.String(32), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.Column("size", sa.Integer(), nullable=False),
        sa.Column("width", sa.Integer(), nullable=False),
        sa.Column("height", sa.Integer(), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("uploaded_by", sa.String(64), nullable=False),
        sa.Column("uploaded_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_guide_images")),
        sa.UniqueConstraint("rig_id", "sha256", name=op.f("uq_guide_images_rig_id_sha256")),
    )


def downgrade() -> None:
    op.drop_table("guide_images")
