"""Calendar feeds: the bookings as an iCalendar (RFC 5545) address a calendar application reads.

A calendar application cannot log in, so the address carries the secret: a
person creates a feed (of every course of theirs, or of one course they are
in) and is shown its address once, ``/api/calendar/<token>.ics``; the lab keeps
the token's SHA-256 only, as it does for API tokens. Revoking the feed deletes
it, and the address answers 404 from then on. A feed answers as its owner
would see the calendar: their courses' slots (a student's feed leaves out
classmates' own bookings), from 30 days back to 180 days ahead; leaving the
course empties a course's feed.

The file is written by the ``icalendar`` package: one ``VEVENT`` per booking,
its ``UID`` stable (``booking-<id>@<lab>``) so that an application updates an
event that moved, instants in UTC.
"""

from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta

from icalendar import Calendar, Event
from sqlalchemy import or_, select

from thermolab.errors import AccessDeniedError, InvalidParameterError, NotFoundError
from thermolab.lab.accounts.policy import Action, Scope, scope_of, who_may
from thermolab.lab.accounts.users import Principal
from thermolab.lab.classes.course_access import course_named, require_member
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.booking_models import Booking, BookingRig
from thermolab.lab.db.booking_tool_models import CalendarFeed
from thermolab.lab.db.models import Course, CourseMember, Role, User

__all__ = ["MAX_FEEDS", "CalendarFeedService", "FeedInfo", "NewFeed"]

MAX_FEEDS = 20
"""The most feeds one person keeps (one per course and device is plenty)."""
_PAST = timedelta(days=30)
_AHEAD = timedelta(days=180)


@dataclass(frozen=True, slots=True)
class FeedInfo:
    """A feed as its owner lists it (never its secret)."""

    id: int
    course: str | None
    created_at: datetime
    last_read_at: datetime | None


@dataclass(frozen=True, slots=True)
class NewFeed:
    """A feed just made: its secret ``token`` is shown this once."""

    feed: FeedInfo
    token: str


def _hash(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


class CalendarFeedService:
    """Create, list and revoke feeds (their owner); answer a feed's address (anyone with it)."""

    def __init__(self, db: Database, clock: LabClock, lab_title: str) -> None:
        self._db = db
        self._clock = clock
        self._title = lab_title

    def create(self, who: Principal, course: str | None) -> NewFeed:
        """A new feed of ``who``'s courses, or of ``course`` (they must be in it).

        Raises
        ------
        AccessDeniedError
            Not in the course, or the policy gives ``who`` no feeds.
        InvalidParameterError
            Already :data:`MAX_FEEDS` feeds.
        """
        _require(who)
        token = secrets.token_urlsafe(32)
        with self._db.write() as session:
            course_id = None
            if course is not None:
                row = course_named(session, course)
                require_member(session, row, who, None, Action.CALENDAR_FEED.value)
                course_id = row.id
            count = len(
                session.scalars(
                    select(CalendarFeed.id).where(CalendarFeed.user_id == who.user_id)
                ).all()
            )
            if count >= MAX_FEEDS:
                raise InvalidParameterError(
                    f"you have {count} calendar feeds, the most one person keeps; revoke one first"
                )
            feed = CalendarFeed(
                user_id=who.user_id,
                course_id=course_id,
                token_hash=_hash(token),
                created_at=self._clock.now(),
            )
            session.add(feed)
            session.flush()
            return NewFeed(FeedInfo(feed.id, course, feed.created_at, None), token)

    def list(self, who: Principal) -> list[FeedInfo]:
        """``who``'s feeds, oldest first."""
        _require(who)
        with self._db.read() as session:
            rows = session.execute(
                select(CalendarFeed, Course.name)
                .outerjoin(Course, Course.id == CalendarFeed.course_id)
                .where(CalendarFeed.user_id == who.user_id)
                .order_by(CalendarFeed.id)
            ).all()
            return [FeedInfo(f.id, name, f.created_at, f.last_read_at) for f, name in rows]

    def revoke(self, who: Principal, feed_id: int) -> None:
        """Delete one of ``who``'s feeds: its address answers 404 from now on.

        Raises
        ------
        NotFoundError
            No such feed of theirs (another person's is not found either).
        """
        _require(who)
        with self._db.write() as session:
            feed = session.get(CalendarFeed, feed_id)
            if feed is None or feed.user_id != who.user_id:
                raise NotFoundError(f"you have no calendar feed number {feed_id}")
            session.delete(feed)

    def ics(self, token: str) -> bytes:
        """The feed's iCalendar file.

        Raises
        ------
        NotFoundError
            An unknown or revoked token, or an owner the policy gives no feed.
        """
        now = self._clock.now()
        with self._db.write() as session:
            feed = session.scalar(
                select(CalendarFeed).where(CalendarFeed.token_hash == _hash(token))
            )
            user = None if feed is None else session.get(User, feed.user_id)
            if feed is None or user is None:
                raise NotFoundError("no such calendar feed (revoked, or the address is wrong)")
            owner = Principal(user.id, user.username, Role(user.role), admin=bool(user.admin))
            if scope_of(owner, Action.CALENDAR_FEED) is Scope.NONE:
                raise NotFoundError("no such calendar feed")
            feed.last_read_at = now
            member = select(CourseMember.course_id).where(CourseMember.user_id == user.id)
            query = (
                select(Booking, Course)
                .join(Course, Course.id == Booking.course_id)
                .where(
                    Booking.course_id.in_(member),
                    Booking.ends_at > now - _PAST,
                    Booking.starts_at < now + _AHEAD,
                )
                .order_by(Booking.starts_at, Booking.id)
            )
            if feed.course_id is not None:
                query = query.where(Booking.course_id == feed.course_id)
            if not owner.is_teacher:
                # A student's calendar: their courses' slots and their own bookings.
                query = query.where(
                    or_(Booking.booked_for.is_(None), Booking.booked_for == user.id)
                )
            calendar = Calendar()
            calendar.add("prodid", f"-//ThermoLab//{self._title}//EN")
            calendar.add("version", "2.0")
            calendar.add("x-wr-calname", self._title)
            for booking, course in session.execute(query).all():
                rigs = sorted(
                    session.scalars(
                        select(BookingRig.rig_id).where(BookingRig.booking_id == booking.id)
                    )
                )
                event = Event()
                event.add("uid", f"booking-{booking.id}@thermolab")
                event.add("dtstamp", booking.updated_at)
                event.add("dtstart", booking.starts_at)
                event.add("dtend", booking.ends_at)
                event.add("summary", f"{course.title}: {', '.join(rigs)}")
                if booking.note:
                    event.add("description", booking.note)
                event.add("location", f"{self._title}: {', '.join(rigs)}")
                calendar.add_component(event)
            ical: bytes = calendar.to_ical()
            return ical


def _require(who: Principal) -> None:
    if scope_of(who, Action.CALENDAR_FEED) is Scope.NONE:
        reach = (Scope.LAB, Scope.TAUGHT, Scope.SELF)
        raise AccessDeniedError(
            f"only {who_may(Action.CALENDAR_FEED, reach)} may {Action.CALENDAR_FEED}"
        )
