"""The tables of bookings: a course's slot on one or more rigs (issue #10, item 5).

A :class:`Booking` is a course's slot, ``[starts_at, ends_at)`` in UTC; its
rigs are :class:`BookingRig` rows. Two bookings that share a rig never
overlap: :mod:`thermolab.lab.classes.bookings` checks that inside the locks of every
rig involved (``SELECT ... FOR UPDATE`` on PostgreSQL, ``BEGIN IMMEDIATE`` on
SQLite), the same locks every turn decision takes.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import CheckConstraint, ForeignKey, Index, Integer, String, UniqueConstraint
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["Booking", "BookingRig"]


class Booking(Base):
    """A course's slot: during it only the course's people may control its rigs."""

    __tablename__ = "bookings"
    __table_args__ = (
        CheckConstraint("ends_at > starts_at", name="ends_after_start"),
        Index("ix_bookings_ends_at", "ends_at"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id", ondelete="CASCADE"), index=True)
    starts_at: Mapped[datetime] = mapped_column(UTCDateTime)
    ends_at: Mapped[datetime] = mapped_column(UTCDateTime)
    note: Mapped[str] = mapped_column(String(200), default="")
    # A student's own booking within the course's quota (null: the teachers' slot).
    booked_for: Mapped[int | None] = mapped_column(
        ForeignKey("users.id", ondelete="CASCADE"), default=None, index=True
    )
    # The weekly series an occurrence was booked with (null: booked alone).
    series: Mapped[str | None] = mapped_column(String(32), default=None, index=True)
    created_by: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime)


class BookingRig(Base):
    """A rig of a booking."""

    __tablename__ = "booking_rigs"
    __table_args__ = (UniqueConstraint("booking_id", "rig_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    booking_id: Mapped[int] = mapped_column(
        ForeignKey("bookings.id", ondelete="CASCADE"), index=True
    )
    rig_id: Mapped[str] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"), index=True)
