"""At most one running run per rig, enforced by the database.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-21

The run service checks it under the rig's lock; this partial unique index is
the last line of defence, as ``ux_control_sessions_active_rig`` is for control.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | None = None
depends_on: str | None = None


def upgrade() -> None:
    op.create_index(
        "ux_runs_running_rig",
        "runs",
        ["rig_id"],
        unique=True,
        sqlite_where=sa.text("status = 'running'"),
        postgresql_where=sa.text("status = 'running'"),
    )


def downgrade() -> None:
    op.drop_index("ux_runs_running_rig", table_name="runs")
