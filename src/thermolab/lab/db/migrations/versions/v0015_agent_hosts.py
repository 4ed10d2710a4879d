"""Rig hosts that dial in (``thermolab agent``): their hashed secrets and last contact.

Revision ID: 0015
Revises: 0009
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0015"
down_revision: str | None = "0014"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    op.create_table(
        "agent_hosts",
        sa.Column("rig_id", sa.String(64), nullable=False),
        sa.Column("secret_hash", sa.String(64), nullable=False),
        sa.Column("issued_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("last_contact", sa.DateTime(timezone=True), nullable=True),
        sa.Column("version", sa.String(64), nullable=True),
        sa.Column("spec", sa.String(200), nullable=True),
        sa.Column("fault", sa.String(500), nullable=True),
        sa.ForeignKeyConstraint(
            ["rig_id"], ["rigs.id"], name=op.f("fk_agent_hosts_rig_id_rigs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("rig_id", name=op.f("pk_agent_hosts")),
    )


def downgrade() -> None:
    op.drop_table("agent_hosts")
