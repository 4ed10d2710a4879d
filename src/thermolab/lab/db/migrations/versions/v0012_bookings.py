"""Bookings: a course's slot on one or more rigs; turns and queue places a slot ends.

Revision ID: 0012
Revises: 0009
Create Date: 2026-11-24

``bookings`` (course, ``[starts_at, ends_at)`` in UTC, note, who booked) and
``booking_rigs`` (its rigs); the reason ``booked`` joins the allowed end
reasons of control sessions and leave reasons of queue entries.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0012"
down_revision: str | None = "0011"
branch_labels: str | None = None
depends_on: str | None = None

_TURN_ENDS = ["released", "time_limit", "idle", "client_gone", "kicked", "rig_fault"]
_LEAVES = ["promoted", "left", "client_gone", "kicked"]


def _in(column: str, values: list[str]) -> str:
    return f"{column} IN ({', '.join(repr(v) for v in values)})"


def _reasons(turn_ends: list[str], leaves: list[str]) -> None:
    with op.batch_alter_table("control_sessions") as batch:
        batch.drop_constraint(op.f("ck_control_sessions_end_reason"), type_="check")
        batch.create_check_constraint(
            op.f("ck_control_sessions_end_reason"), _in("end_reason", turn_ends)
        )
    with op.batch_alter_table("queue_entries") as batch:
        batch.drop_constraint(op.f("ck_queue_entries_leave_reason"), type_="check")
        batch.create_check_constraint(
            op.f("ck_queue_entries_leave_reason"), _in("leave_reason", leaves)
        )


def upgrade() -> None:
    op.create_table(
        "bookings",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("course_id", sa.Integer(), nullable=False),
        sa.Column("starts_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("ends_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("note", sa.String(200), nullable=False),
        sa.Column("created_by", sa.String(64), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("ends_at > starts_at", name=op.f("ck_bookings_ends_after_start")),
        sa.ForeignKeyConstraint(
            ["course_id"],
            ["courses.id"],
            name=op.f("fk_bookings_course_id_courses"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_bookings")),
    )
    op.create_index(op.f("ix_bookings_course_id"), "bookings", ["course_id"], unique=False)
    op.create_index("ix_bookings_ends_at", "bookings", ["ends_at"], unique=False)
    op.create_table(
        "booking_rigs",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("booking_id", sa.Integer(), nullable=False),
        sa.Column("rig_id", sa.String(64), nullable=False),
        sa.ForeignKeyConstraint(
            ["booking_id"],
            ["bookings.id"],
            name=op.f("fk_booking_rigs_booking_id_bookings"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["rig_id"], ["rigs.id"], name=op.f("fk_booking_rigs_rig_id_rigs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_booking_rigs")),
        sa.UniqueConstraint("booking_id", "rig_id", name=op.f("uq_booking_rigs_booking_id_rig_id")),
    )
    op.create_index(
        op.f("ix_booking_rigs_booking_id"), "booking_rigs", ["booking_id"], unique=False
    )
    op.create_index(op.f("ix_booking_rigs_rig_id"), "booking_rigs", ["rig_id"], unique=False)
    _reasons(
        [*_TURN_ENDS, "server_restart", "booked"],
        [*_LEAVES, "server_restart", "booked"],
    )


def downgrade() -> None:
    op.execute("UPDATE control_sessions SET end_reason = 'kicked' WHERE end_reason = 'booked'")
    op.execute("UPDATE queue_entries SET leave_reason = 'kicked' WHERE leave_reason = 'booked'")
    _reasons([*_TURN_ENDS, "server_restart"], [*_LEAVES, "server_restart"])
    op.drop_index(op.f("ix_booking_rigs_rig_id"), table_name="booking_rigs")
    op.drop_index(op.f("ix_booking_rigs_booking_id"), table_name="booking_rigs")
    op.drop_table("booking_rigs")
    op.drop_index("ix_bookings_ends_at", table_name="bookings")
    op.drop_index(op.f("ix_bookings_course_id"), table_name="bookings")
    op.drop_table("bookings")
