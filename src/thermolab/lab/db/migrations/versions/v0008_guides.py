"""Guide pages per rig and their revisions (thermolab.lab.guides).

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0008"
down_revision: str | None = "0007"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    op.create_table(
        "guide_pages",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("rig_id", sa.String(64), nullable=False),
        sa.Column("lang", sa.String(8), nullable=False),
        sa.Column("section", sa.String(32), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_guide_pages")),
        sa.UniqueConstraint(
            "rig_id", "lang", "section", name=op.f("uq_guide_pages_rig_id_lang_section")
        ),
    )
    op.create_table(
        "guide_revisions",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("page_id", sa.Integer(), nullable=False),
        sa.Column("markdown", sa.Text(), nullable=False),
        sa.Column("author", sa.String(64), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("restored_from", sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(
            ["page_id"],
            ["guide_pages.id"],
            name=op.f("fk_guide_revisions_page_id_guide_pages"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_guide_revisions")),
    )
    op.create_index(
        op.f("ix_guide_revisions_page_id"), "guide_revisions", ["page_id"], unique=False
    )


def downgrade() -> None:
    op.drop_index(op.f("ix_guide_revisions_page_id"), table_name="guide_revisions")
    op.drop_table("guide_revisions")
    op.drop_table("guide_pages")
