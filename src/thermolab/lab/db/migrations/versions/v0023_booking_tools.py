"""The teachers' booking tools: students' own bookings, weekly series, calendar feeds, reminders.

Revision ID: 0023
Revises: 0022
Create Date: 2026-11-28

``bookings.booked_for`` (a student's own booking within their course's quota)
and ``bookings.series`` (the weekly series an occurrence belongs to);
``course_booking_quotas`` (minutes a week a course's students may book for
themselves), ``calendar_feeds`` (secret iCalendar addresses, their SHA-256
only), ``reminder_addresses`` (where a person wants booking reminders) and
``reminders_sent`` (each reminder sent, so that none goes twice).
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0023"
down_revision: str | None = "0022"
branch_labels: str | None = None
depends_on: str | None = None

_WHEN = sa.DateTime(timezone=True)


def _user_fk(table: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        ["user_id"], ["users.id"], name=op.f(f"fk_{table}_user_id_users"), ondelete="CASCADE"
    )


def _course_fk(table: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        ["course_id"],
        ["courses.id"],
        name=op.f(f"fk_{table}_course_id_courses"),
        ondelete="CASCADE",
    )


def upgrade() -> None:
    with op.batch_alter_table("bookings") as batch:
        batch.add_column(sa.Column("booked_for", sa.Integer(), nullable=True))
        batch.add_column(sa.Column("series", sa.String(32), nullable=True))
        batch.create_foreign_key(
            op.f("fk_bookings_booked_for_users"),
            "users",
            ["booked_for"],
            ["id"],
            ondelete="CASCADE",
        )
        batch.create_index(op.f("ix_bookings_booked_for"), ["booked_for"], unique=False)
        batch.create_index(op.f("ix_bookings_series"), ["series"], unique=False)
    op.create_table(
        "course_booking_quotas",
        sa.Column("course_id", sa.Integer(), nullable=False),
        sa.Column("minutes_per_week", sa.Integer(), nullable=False),
        sa.Column("updated_at", _WHEN, nullable=False),
        sa.Column("updated_by", sa.String(64), nullable=False),
        _course_fk("course_booking_quotas"),
        sa.PrimaryKeyConstraint("course_id", name=op.f("pk_course_booking_quotas")),
    )
    op.create_table(
        "calendar_feeds",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("course_id", sa.Integer(), nullable=True),
        sa.Column("token_hash", sa.String(64), nullable=False),
        sa.Column("created_at", _WHEN, nullable=False),
        sa.Column("last_read_at", _WHEN, nullable=True),
        _user_fk("calendar_feeds"),
        _course_fk("calendar_feeds"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_calendar_feeds")),
        sa.UniqueConstraint("token_hash", name=op.f("uq_calendar_feeds_token_hash")),
    )
    op.create_index(op.f("ix_calendar_feeds_user_id"), "calendar_feeds", ["user_id"])
    op.create_table(
        "reminder_addresses",
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("email", sa.String(254), nullable=False),
        sa.Column("minutes_before", sa.Integer(), nullable=False),
        sa.Column("language", sa.String(8), nullable=False),
        _user_fk("reminder_addresses"),
        sa.PrimaryKeyConstraint("user_id", name=op.f("pk_reminder_addresses")),
    )
    op.create_table(
        "reminders_sent",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("booking_id", sa.Integer(), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("sent_at", _WHEN, nullable=False),
        sa.ForeignKeyConstraint(
            ["booking_id"],
            ["bookings.id"],
            name=op.f("fk_reminders_sent_booking_id_bookings"),
            ondelete="CASCADE",
        ),
        _user_fk("reminders_sent"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_reminders_sent")),
        sa.UniqueConstraint(
            "booking_id", "user_id", name=op.f("uq_reminders_sent_booking_id_user_id")
        ),
    )
    op.create_index(op.f("ix_reminders_sent_booking_id"), "reminders_sent", ["booking_id"])


def downgrade() -> None:
    op.drop_index(op.f("ix_reminders_sent_booking_id"), table_name="reminders_sent")
    op.drop_table("reminders_sent")
    op.drop_table("reminder_addresses")
    op.drop_index(op.f("ix_calendar_feeds_user_id"), table_name="calendar_feeds")
    op.drop_table("calendar_feeds")
    op.drop_table("course_booking_quotas")
    with op.batch_alter_table("bookings") as batch:
        batch.drop_index(op.f("ix_bookings_series"))
        batch.drop_index(op.f("ix_bookings_booked_for"))
        batch.drop_constraint(op.f("fk_bookings_booked_for_users"), type_="foreignkey")
        batch.drop_column("series")
        batch.drop_column("booked_for")
