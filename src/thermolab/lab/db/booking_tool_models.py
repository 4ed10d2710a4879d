"""The tables of the teachers' booking tools (issue #24, item 7).

:class:`CourseBookingQuota` lets a course's students book free slots for
themselves, up to so many minutes a week; :class:`CalendarFeed` is a secret
address a calendar application reads the bookings from (the token's SHA-256
only: the address is shown once); :class:`ReminderAddress` is where a person
asked for booking reminders, and :class:`ReminderSent` records each reminder
sent, so that none is sent twice, across restarts and workers alike.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import ForeignKey, Integer, String, UniqueConstraint
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["CalendarFeed", "CourseBookingQuota", "ReminderAddress", "ReminderSent"]


class CourseBookingQuota(Base):
    """How many minutes a week each student of a course may book for themselves."""

    __tablename__ = "course_booking_quotas"

    course_id: Mapped[int] = mapped_column(
        ForeignKey("courses.id", ondelete="CASCADE"), primary_key=True
    )
    minutes_per_week: Mapped[int] = mapped_column(Integer)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime)
    updated_by: Mapped[str] = mapped_column(String(64))


class CalendarFeed(Base):
    """A person's secret iCalendar address: every course of theirs, or one (``course_id``)."""

    __tablename__ = "calendar_feeds"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    course_id: Mapped[int | None] = mapped_column(
        ForeignKey("courses.id", ondelete="CASCADE"), default=None
    )
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)
    last_read_at: Mapped[datetime | None] = mapped_column(UTCDateTime, default=None)


class ReminderAddress(Base):
    """Where and how long before a booking a person wants an e-mail reminder."""

    __tablename__ = "reminder_addresses"

    user_id: Mapped[int] = mapped_column(
        ForeignKey("users.id", ondelete="CASCADE"), primary_key=True
    )
    email: Mapped[str] = mapped_column(String(254))
    minutes_before: Mapped[int] = mapped_column(Integer)
    # The language the reminders are written in (the page's when the address was set).
    language: Mapped[str] = mapped_column(String(8), default="en")


class ReminderSent(Base):
    """A reminder of a booking sent to a person (written before sending: at most once)."""

    __tablename__ = "reminders_sent"
    __table_args__ = (UniqueConstraint("booking_id", "user_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    booking_id: Mapped[int] = mapped_column(
        ForeignKey("bookings.id", ondelete="CASCADE"), index=True
    )
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"))
    sent_at: Mapped[datetime] = mapped_column(UTCDateTime)
