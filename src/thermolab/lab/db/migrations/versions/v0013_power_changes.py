"""Every change of a rig's power state (class analytics: hours powered).

Revision ID: 0013
Revises: 0009
Create Date: 2026-11-24

Before this revision only the current state was kept, so the history starts
here: each rig gets one row with its state as it is now, dated when it last
changed.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0013"
down_revision: str | None = "0012"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    op.create_table(
        "rig_power_changes",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("rig_id", sa.String(64), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("state", sa.String(16), nullable=False),
        sa.CheckConstraint(
            "state IN ('off', 'on', 'cooling')", name=op.f("ck_rig_power_changes_state")
        ),
        sa.ForeignKeyConstraint(
            ["rig_id"],
            ["rigs.id"],
            name=op.f("fk_rig_power_changes_rig_id_rigs"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_rig_power_changes")),
    )
    op.create_index(
        "ix_rig_power_changes_rig_id_at", "rig_power_changes", ["rig_id", "at"], unique=False
    )
    op.execute(
        "INSERT INTO rig_power_changes (rig_id, at, state) "
        "SELECT id, power_changed_at, power_state FROM rigs"
    )


def downgrade() -> None:
    op.drop_index("ix_rig_power_changes_rig_id_at", table_name="rig_power_changes")
    op.drop_table("rig_power_changes")
