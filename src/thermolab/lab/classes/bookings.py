"""Bookings: a teacher reserves rigs for a course's slot; the calendar; a student's next chance.

What a slot *does* (only the course's people control its rigs, the queue
inside it, an outsider's turn ending at its start) is the turn rules'
(:mod:`thermolab.lab.access.rules`); this module keeps the calendar.

Overlaps are refused atomically. A booking is written in one transaction that
first locks the row of every rig it names, in a fixed (sorted) order so that
two bookings never wait on each other: ``SELECT ... FOR UPDATE`` on
PostgreSQL, and on SQLite the write transaction's ``BEGIN IMMEDIATE``, which
holds the database's one write lock. The overlap check and the insert then
run with no other booking of those rigs in between, so of two teachers
booking overlapping slots at once exactly one wins and the other gets a 409
``booking_clash`` naming the slot that won. These are the same rig locks every
turn decision takes; a PostgreSQL exclusion constraint would need the
``btree_gist`` extension and has no SQLite equivalent, so the lock is the one
mechanism on both databases.

Times are UTC instants (``[starts_at, ends_at)``); the browser shows them in the
reader's time zone and locale. A student sees their own courses' slots with
the course named and other courses' slots only as "reserved" (which course
booked a rig is none of their business; teachers see every slot).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import ColumnElement, select
from sqlalchemy.orm import Session

from thermolab.errors import BookingClashError, InvalidParameterError, NotFoundError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.classes.closed import require_open
from thermolab.lab.classes.course_access import course_named, require_member
from thermolab.lab.classes.slot_times import MAX_SLOT_HOURS, check_slot
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.booking_models import Booking, BookingRig
from thermolab.lab.db.models import Course, CourseMember, Role

__all__ = [
    "MAX_CALENDAR_DAYS",
    "MAX_SLOT_HOURS",
    "BookingInfo",
    "BookingService",
    "NextChance",
    "booking_info",
    "refuse_clash",
]

MAX_CALENDAR_DAYS = 62
"""The longest window one calendar request may ask for."""
_MAX_RIGS = 20
_MAX_NOTE = 200


@dataclass(frozen=True, slots=True)
class BookingInfo:
    """A booking as one reader sees it.

    ``course`` and ``course_title`` are ``None`` for a student looking at
    another course's slot; ``own`` says whether the reader is in its course.
    """

    id: int
    course: str | None
    course_title: str | None
    own: bool
    rigs: tuple[str, ...]
    starts_at: datetime
    ends_at: datetime
    note: str
    created_by: str | None
    self_booked: bool = False
    mine: bool = False
    series: str | None = None


@dataclass(frozen=True, slots=True)
class NextChance:
    """When a user may next take a rig's controls, by the bookings.

    ``booked_now`` is the slot going on, if any; ``free_from`` the instant
    the reader may queue again when that slot is another course's (``None``:
    now); ``next_own`` the next slot of one of the reader's courses.
    """

    booked_now: BookingInfo | None
    free_from: datetime | None
    next_own: BookingInfo | None


class BookingService:
    """Book, edit and cancel slots (teachers); read the calendar and next chances (anyone).

    Parameters
    ----------
    db : Database
    clock : LabClock
    config : LabConfig
        The rigs that may be booked.
    """

    def __init__(self, db: Database, clock: LabClock, config: LabConfig) -> None:
        self._db = db
        self._clock = clock
        self._config = config

    def create(
        self,
        who: Principal,
        course: str,
        rigs: list[str],
        starts_at: datetime,
        ends_at: datetime,
        note: str = "",
        *,
        longer: bool = False,
    ) -> BookingInfo:
        """Book ``rigs`` for ``course`` from ``starts_at`` to ``ends_at`` (its teachers only).

        ``longer``: the teacher says the slot is longer than a day on purpose.

        Raises
        ------
        AccessDeniedError
            If ``who`` is not a teacher of the course.
        InvalidParameterError
            Naive or reversed times, a slot longer than a day or already over,
            no rigs or too many, a note too long.
        NotFoundError
            An unknown course or rig.
        BookingClashError
            If the slot overlaps another booking of one of the rigs.
        """
        who.require_teacher("book rigs")
        starts_at, ends_at, wanted = self.check(rigs, starts_at, ends_at, note, longer=longer)
        now = self._clock.now()
        with self._db.write() as session:
            # Locked: a close that is under way finishes first, and this sees it closed.
            course_row = course_named(session, course, lock=True)
            require_member(session, course_row, who, Role.TEACHER, "book rigs for it")
            require_open(course_row, "book rigs for it")
            self.lock(session, wanted)
            refuse_clash(session, wanted, starts_at, ends_at, exclude=None)
            booking = Booking(
                course_id=course_row.id,
                starts_at=starts_at,
                ends_at=ends_at,
                note=note.strip(),
                created_by=who.username,
                created_at=now,
                updated_at=now,
            )
            session.add(booking)
            session.flush()
            session.add_all(BookingRig(booking_id=booking.id, rig_id=rig) for rig in wanted)
            session.flush()
            return booking_info(session, booking, who, teacher=True)

    def update(
        self,
        who: Principal,
        booking_id: int,
        rigs: list[str],
        starts_at: datetime,
        ends_at: datetime,
        note: str = "",
        *,
        longer: bool = False,
    ) -> BookingInfo:
        """Move a booking or change its rigs (its course's teachers); checks as :meth:`create`.

        Raises
        ------
        NotFoundError
            If there is no such booking.
        """
        who.require_teacher("edit bookings")
        starts_at, ends_at, wanted = self.check(rigs, starts_at, ends_at, note, longer=longer)
        with self._db.write() as session:
            booking = _booking(session, booking_id)
            _require_course_teacher(session, booking, who, "move its bookings")
            old = set(session.scalars(select(BookingRig.rig_id).where(_of(booking.id))))
            self.lock(session, sorted(old | set(wanted)))
            refuse_clash(session, wanted, starts_at, ends_at, exclude=booking.id)
            booking.starts_at = starts_at
            booking.ends_at = ends_at
            booking.note = note.strip()
            booking.updated_at = self._clock.now()
            for row in session.scalars(select(BookingRig).where(_of(booking.id))):
                if row.rig_id not in wanted:
                    session.delete(row)
            session.add_all(
                BookingRig(booking_id=booking.id, rig_id=rig) for rig in wanted if rig not in old
            )
            session.flush()
            return booking_info(session, booking, who, teacher=True)

    def cancel(self, who: Principal, booking_id: int) -> None:
        """Cancel a booking (its course's teachers, or the student who booked it for
        themselves); the rules stop applying it at once.

        Raises
        ------
        NotFoundError
            If there is no such booking.
        """
        with self._db.write() as session:
            booking = _booking(session, booking_id)
            if booking.booked_for is not None and booking.booked_for == who.user_id:
                course = session.get(Course, booking.course_id, with_for_update=True)
                assert course is not None  # a course's bookings go with it
                require_open(course, "cancel its bookings")
            else:
                who.require_teacher("cancel bookings")
                _require_course_teacher(session, booking, who, "cancel its bookings")
            rigs = sorted(session.scalars(select(BookingRig.rig_id).where(_of(booking.id))))
            self.lock(session, rigs)
            session.delete(booking)

    def calendar(
        self, who: Principal, start: datetime, end: datetime, rig: str | None = None
    ) -> list[BookingInfo]:
        """The bookings that overlap ``[start, end)``, by start, as ``who`` sees them.

        Raises
        ------
        InvalidParameterError
            Naive or reversed times, or a window longer than :data:`MAX_CALENDAR_DAYS`.
        NotFoundError
            An unknown rig.
        """
        _aware(start, "from")
        _aware(end, "to")
        if not start < end <= start + timedelta(days=MAX_CALENDAR_DAYS):
            raise InvalidParameterError(
                f"the calendar's window must end after it starts and span at most "
                f"{MAX_CALENDAR_DAYS} days, got {start.isoformat()} to {end.isoformat()}"
            )
        if rig is not None:
            self._config.rig(rig)
        query = select(Booking).where(Booking.starts_at < end, Booking.ends_at > start)
        if rig is not None:
            query = query.where(
                Booking.id.in_(select(BookingRig.booking_id).where(BookingRig.rig_id == rig))
            )
        with self._db.read() as session:
            bookings = list(session.scalars(query.order_by(Booking.starts_at, Booking.id)))
            return [booking_info(session, b, who, teacher=who.is_teacher) for b in bookings]

    def next_chance(self, who: Principal, rig: str) -> NextChance:
        """When ``who`` may next take ``rig``'s controls, by the bookings of the coming fortnight.

        Raises
        ------
        NotFoundError
            An unknown rig.
        """
        now = self._clock.now()
        slots = self.calendar(who, now, now + timedelta(days=14), rig)
        booked_now = next((b for b in slots if b.starts_at <= now < b.ends_at), None)
        free_from = None
        if booked_now is not None and not booked_now.own:
            # Back-to-back slots of other courses keep the rig closed until the last ends.
            free_from = booked_now.ends_at
            for b in slots:
                if b.starts_at == free_from and not b.own:
                    free_from = b.ends_at
        next_own = next((b for b in slots if b.own and b.starts_at > now), None)
        return NextChance(booked_now, free_from, next_own)

    # -- helpers ---------------------------------------------------------------------

    def check(
        self,
        rigs: list[str],
        starts_at: datetime,
        ends_at: datetime,
        note: str,
        *,
        longer: bool = False,
    ) -> tuple[datetime, datetime, list[str]]:
        """The slot in UTC and its rigs sorted, or refuse them (see :meth:`create`)."""
        starts_at, ends_at = check_slot(starts_at, ends_at, longer=longer)
        if ends_at <= self._clock.now():
            raise InvalidParameterError("the slot is already over; book one that ends later")
        wanted = sorted(set(rigs))
        if not 0 < len(wanted) <= _MAX_RIGS:
            raise InvalidParameterError(f"book 1 to {_MAX_RIGS} rigs, got {len(wanted)}")
        for rig in wanted:
            self._config.rig(rig)
        if len(note.strip()) > _MAX_NOTE:
            raise InvalidParameterError(f"a note may have at most {_MAX_NOTE} characters")
        return starts_at, ends_at, wanted

    def lock(self, session: Session, rigs: list[str]) -> None:
        """Lock the rows of ``rigs`` for a booking's clash check and write."""
        # Sorted: two transactions locking overlapping sets never wait on each other.
        for rig in sorted(rigs):
            self._db.lock_rig(session, rig)


def _aware(t: datetime, name: str) -> None:
    if t.tzinfo is None or t.utcoffset() is None:
        raise InvalidParameterError(
            f"{name} must carry a time zone (an ISO 8601 instant such as "
            f"2026-03-02T13:00:00Z), got {t.isoformat()}"
        )


def _of(booking_id: int) -> ColumnElement[bool]:
    return BookingRig.booking_id == booking_id


def _booking(session: Session, booking_id: int) -> Booking:
    booking = session.get(Booking, booking_id)
    if booking is None:
        raise NotFoundError(f"no booking number {booking_id}")
    return booking


def refuse_clash(
    session: Session,
    rigs: list[str],
    starts_at: datetime,
    ends_at: datetime,
    *,
    exclude: int | None,
) -> None:
    """Refuse a slot that overlaps another booking of one of ``rigs`` (the rigs locked)."""
    query = (
        select(Booking, BookingRig.rig_id)
        .join(BookingRig, BookingRig.booking_id == Booking.id)
        .where(
            BookingRig.rig_id.in_(rigs),
            Booking.starts_at < ends_at,
            Booking.ends_at > starts_at,
        )
        .order_by(Booking.starts_at, Booking.id)
    )
    if exclude is not None:
        query = query.where(Booking.id != exclude)
    rows = session.execute(query).all()
    if not rows:
        return
    other = rows[0][0]
    shared = sorted({rig for b, rig in rows if b.id == other.id})
    course = session.get(Course, other.course_id)
    name = course.name if course is not None else "?"
    raise BookingClashError(
        f"the slot overlaps the booking of course {name!r} on {', '.join(shared)} from "
        f"{other.starts_at:%Y-%m-%d %H:%M} to {other.ends_at:%Y-%m-%d %H:%M} UTC; "
        "choose another time or other rigs",
        {
            "id": other.id,
            "course": name,
            "startsAt": other.starts_at.isoformat(),
            "endsAt": other.ends_at.isoformat(),
            "rigs": shared,
        },
    )


def booking_info(
    session: Session, booking: Booking, who: Principal, *, teacher: bool
) -> BookingInfo:
    rigs = tuple(
        session.scalars(
            select(BookingRig.rig_id).where(_of(booking.id)).order_by(BookingRig.rig_id)
        )
    )
    own = (
        session.scalar(
            select(CourseMember.id).where(
                CourseMember.course_id == booking.course_id, CourseMember.user_id == who.user_id
            )
        )
        is not None
    )
    course = session.get(Course, booking.course_id)
    shown = teacher or own
    return BookingInfo(
        id=booking.id,
        course=course.name if course is not None and shown else None,
        course_title=course.title if course is not None and shown else None,
        own=own,
        rigs=rigs,
        starts_at=booking.starts_at,
        ends_at=booking.ends_at,
        note=booking.note if shown else "",
        created_by=booking.created_by if shown else None,
        self_booked=booking.booked_for is not None,
        mine=booking.booked_for is not None and booking.booked_for == who.user_id,
        series=booking.series if shown else None,
    )


def _require_course_teacher(
    session: Session, booking: Booking, who: Principal, action: str
) -> None:
    # Locked, as in create: a close under way finishes first (and may cancel the booking).
    course = session.get(Course, booking.course_id, with_for_update=True)
    assert course is not None  # a course's bookings go with it (ON DELETE CASCADE)
    if session.get(Booking, booking.id, populate_existing=True) is None:
        raise NotFoundError(f"no booking number {booking.id}")
    require_member(session, course, who, Role.TEACHER, action)
    require_open(course, action)
