"""The teachers' booking tools: students' own bookings within a quota, weekly series.

**Students' own bookings.** A course's teachers set ``student_booking_quota``:
the minutes a week each student may book for themselves (0, the default:
students book nothing). The week is the ISO week of the slot's start in the
lab's ``time_zone``, Monday 00:00 to Monday 00:00 there (a class in São Paulo
counts Sunday evening's slot in Sunday's week, not in the next UTC week); what
counts is the student's own bookings of that course starting in that week. A
student books a free slot of one of their course's rigs (every rig when the
course chose none); the slot is a
normal booking of the course (the turn rules give its rigs to the course's
people during it) that records who booked it, and that student may cancel it.

**Weekly series.** A teacher books the same slot every week until a date; each
occurrence is a normal booking (edited or cancelled alone) carrying the
series' id. The weeks keep the first slot's wall-clock time in a time zone
(the request's, else the lab's ``time_zone``), so a change of daylight saving
moves their UTC instants, never the hour on the class's timetable.
Occurrences that overlap other bookings are listed (409
``booking_series_clash``, nothing booked), or with ``skip_clashes`` left out
and the others booked — all in one transaction under the rigs' locks, as one
booking is.

Both ask the policy (:mod:`thermolab.lab.accounts.policy`) first.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from datetime import UTC, date, datetime, time, timedelta, tzinfo

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    BookingClashError,
    BookingQuotaError,
    BookingSeriesClashError,
    InvalidParameterError,
)
from thermolab.lab.accounts.policy import Action, Scope, scope_of, who_may
from thermolab.lab.accounts.users import Principal
from thermolab.lab.classes.bookings import BookingInfo, BookingService, booking_info, refuse_clash
from thermolab.lab.classes.closed import require_open
from thermolab.lab.classes.course_access import course_named, require_member
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.config.time_zones import zone_named
from thermolab.lab.db import Database
from thermolab.lab.db.booking_models import Booking, BookingRig
from thermolab.lab.db.booking_tool_models import CourseBookingQuota
from thermolab.lab.db.models import Course, CourseMember, CourseRig, MemberRole, Role

__all__ = [
    "MAX_QUOTA_MINUTES",
    "MAX_SERIES_WEEKS",
    "BookingTools",
    "OwnBookingCourse",
    "SeriesResult",
    "week_of",
    "weekly",
]

MAX_QUOTA_MINUTES = 7 * 24 * 60
"""The largest weekly quota (a week's minutes)."""
MAX_SERIES_WEEKS = 30
"""The most weeks one series books (a term)."""


@dataclass(frozen=True, slots=True)
class OwnBookingCourse:
    """A course whose student may book for themselves: its quota and their use this week."""

    course: str
    title: str
    minutes_per_week: int
    used_minutes: int
    week_starts_at: datetime
    rigs: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class SeriesResult:
    """The occurrences a series booked, and those left out because they clashed."""

    series: str
    zone: str
    booked: list[BookingInfo]
    skipped: list[dict[str, object]]


def week_of(t: datetime, zone: tzinfo = UTC) -> tuple[datetime, datetime]:
    """The ISO week holding ``t`` in ``zone``: its Monday 00:00 and the next, as UTC instants.

    A week that changes daylight saving lasts 167 or 169 hours.

    >>> from zoneinfo import ZoneInfo
    >>> sunday_evening = datetime(2026, 3, 9, 1, 30, tzinfo=UTC)  # 22:30 on Sunday the 8th
    >>> [d.isoformat() for d in week_of(sunday_evening, ZoneInfo("America/Sao_Paulo"))]
    ['2026-03-02T03:00:00+00:00', '2026-03-09T03:00:00+00:00']
    >>> week_of(sunday_evening)[0].isoformat()
    '2026-03-09T00:00:00+00:00'
    """
    local = t.astimezone(zone)
    monday = local.date() - timedelta(days=local.weekday())
    return tuple(  # type: ignore[return-value]
        datetime.combine(monday + timedelta(days=d), time(0), tzinfo=zone).astimezone(UTC)
        for d in (0, 7)
    )


def weekly(
    start: datetime, end: datetime, until: date, zone: tzinfo
) -> list[tuple[datetime, datetime]]:
    """The slot ``start``–``end`` each week through the day ``until``, at the same wall-clock
    time in ``zone`` (UTC instants; each as long as the first).

    ``until`` is a day in ``zone``. A wall-clock time that a change of daylight saving
    skips (02:30 the night clocks go forward) is the instant an hour later on the clock.

    >>> from zoneinfo import ZoneInfo
    >>> first = datetime(2026, 3, 2, 14, tzinfo=UTC)  # 09:00 in New York (EST)
    >>> new_york = ZoneInfo("America/New_York")
    >>> weeks = weekly(first, first + timedelta(hours=1), date(2026, 3, 9), new_york)
    >>> [a.strftime("%m-%d %H:%M") for a, _ in weeks]  # EDT from 8 March: 09:00 is 13:00 UTC
    ['03-02 14:00', '03-09 13:00']
    """
    local = start.astimezone(zone)
    length = end - start
    weeks = []
    for k in range(MAX_SERIES_WEEKS + 1):
        day = local.date() + timedelta(weeks=k)
        if day > until:
            break
        a = datetime.combine(day, local.time(), tzinfo=zone).astimezone(UTC)
        weeks.append((a, a + length))
    return weeks


class BookingTools:
    """Quotas and students' own bookings; weekly series.

    Parameters
    ----------
    db : Database
    clock : LabClock
    config : LabConfig
    bookings : BookingService
        Checks slots and locks rigs as a single booking does.
    """

    def __init__(
        self, db: Database, clock: LabClock, config: LabConfig, bookings: BookingService
    ) -> None:
        self._db = db
        self._clock = clock
        self._config = config
        self._bookings = bookings

    # -- the quota -------------------------------------------------------------------

    def quota(self, who: Principal, course: str) -> int:
        """The course's weekly minutes per student (its teachers, administrators)."""
        _require(who, Action.BOOKING_QUOTA)
        with self._db.read() as session:
            row = course_named(session, course)
            require_member(session, row, who, Role.TEACHER, Action.BOOKING_QUOTA.value)
            quota = session.get(CourseBookingQuota, row.id)
            return 0 if quota is None else quota.minutes_per_week

    def set_quota(self, who: Principal, course: str, minutes_per_week: int) -> int:
        """Set the course's weekly minutes per student (0: students book nothing)."""
        _require(who, Action.BOOKING_QUOTA)
        if not 0 <= minutes_per_week <= MAX_QUOTA_MINUTES:
            raise InvalidParameterError(
                f"a weekly quota is 0 to {MAX_QUOTA_MINUTES} minutes, got {minutes_per_week}"
            )
        with self._db.write() as session:
            row = course_named(session, course, lock=True)
            require_member(session, row, who, Role.TEACHER, Action.BOOKING_QUOTA.value)
            require_open(row, "change its booking quota")
            quota = session.get(CourseBookingQuota, row.id)
            if quota is None:
                quota = CourseBookingQuota(course_id=row.id)
                session.add(quota)
            quota.minutes_per_week = minutes_per_week
            quota.updated_at = self._clock.now()
            quota.updated_by = who.username
            return minutes_per_week

    # -- students' own bookings ------------------------------------------------------

    def own_courses(self, who: Principal) -> list[OwnBookingCourse]:
        """The open courses ``who`` is a student of that let students book, with this week's use."""
        if scope_of(who, Action.BOOKING_OWN) is Scope.NONE:
            return []
        week = week_of(self._clock.now(), zone_named(self._config.time_zone))
        with self._db.read() as session:
            rows = session.execute(
                select(Course, CourseBookingQuota.minutes_per_week)
                .join(CourseMember, CourseMember.course_id == Course.id)
                .join(CourseBookingQuota, CourseBookingQuota.course_id == Course.id)
                .where(
                    CourseMember.user_id == who.user_id,
                    CourseMember.role == MemberRole.STUDENT.value,
                    CourseBookingQuota.minutes_per_week > 0,
                    Course.closed_at.is_(None),
                )
                .order_by(Course.name)
            ).all()
            return [
                OwnBookingCourse(
                    course=c.name,
                    title=c.title,
                    minutes_per_week=minutes,
                    used_minutes=_used(session, c.id, who.user_id, week),
                    week_starts_at=week[0],
                    rigs=tuple(self._course_rigs(session, c.id)),
                )
                for c, minutes in rows
            ]

    def book_own(
        self, who: Principal, course: str, rig: str, starts_at: datetime, ends_at: datetime
    ) -> BookingInfo:
        """Book a free slot of ``rig`` for ``who`` themselves, within the course's quota.

        Raises
        ------
        AccessDeniedError
            Not a student of the course, a rig the course does not use, or a
            course whose teachers set no quota.
        SlotTimeError, InvalidParameterError
            As a teacher's booking (never longer than a day).
        BookingQuotaError
            The slot would pass the week's quota (409 ``booking_quota_exceeded``).
        BookingClashError
            The slot is not free.
        """
        _require(who, Action.BOOKING_OWN)
        start, end, wanted = self._bookings.check([rig], starts_at, ends_at, "")
        if start < self._clock.now():
            raise InvalidParameterError("book a slot that starts later than now")
        now = self._clock.now()
        with self._db.write() as session:
            row = course_named(session, course, lock=True)
            require_member(session, row, who, Role.STUDENT, Action.BOOKING_OWN.value)
            require_open(row, "book its rigs")
            if rig not in self._course_rigs(session, row.id):
                raise AccessDeniedError(f"course {row.name!r} does not use rig {rig!r}")
            quota = session.get(CourseBookingQuota, row.id)
            minutes = 0 if quota is None else quota.minutes_per_week
            if minutes <= 0:
                raise AccessDeniedError(
                    f"the teachers of course {row.name!r} have not let students book for "
                    "themselves (no weekly quota)"
                )
            # Locked before counting: two of the student's bookings at once cannot both fit.
            self._bookings.lock(session, wanted)
            zone = zone_named(self._config.time_zone)
            week = week_of(start, zone)
            used = _used(session, row.id, who.user_id, week)
            length = round((end - start).total_seconds() / 60)
            if used + length > minutes:
                raise BookingQuotaError(
                    f"the week from {week[0].astimezone(zone):%Y-%m-%d} has {minutes - used} "
                    f"of your {minutes} "
                    f"minutes left in course {row.name!r}; this slot takes {length}",
                    {
                        "minutesPerWeek": minutes,
                        "usedMinutes": used,
                        "weekStartsAt": week[0].isoformat(),
                    },
                )
            refuse_clash(session, wanted, start, end, exclude=None)
            booking = _insert(session, row.id, wanted, start, end, who, now, booked_for=who.user_id)
            return booking_info(session, booking, who, teacher=False)

    # -- weekly series ---------------------------------------------------------------

    def book_series(
        self,
        who: Principal,
        course: str,
        rigs: list[str],
        starts_at: datetime,
        ends_at: datetime,
        until: date,
        *,
        note: str = "",
        longer: bool = False,
        skip_clashes: bool = False,
        zone: str | None = None,
    ) -> SeriesResult:
        """Book the slot every week from ``starts_at`` through the day ``until`` (inclusive).

        The weeks keep the first slot's wall-clock time in ``zone`` (an IANA name;
        ``None``: the lab's ``time_zone``), across changes of daylight saving
        (:func:`weekly`); ``until`` is a day in that zone.

        Raises
        ------
        TimeZoneError
            ``zone`` is not a known IANA time zone (422 ``time_zone_unknown``).
        BookingSeriesClashError
            Some occurrences clash and ``skip_clashes`` is false; nothing booked.
        InvalidParameterError
            ``until`` before the first occurrence, or more than
            :data:`MAX_SERIES_WEEKS` weeks.
        """
        _require(who, Action.BOOKING_SERIES)
        who.require_teacher("book rigs")
        start, end, wanted = self._bookings.check(rigs, starts_at, ends_at, note, longer=longer)
        zone_name = zone or self._config.time_zone
        weeks = weekly(start, end, until, zone_named(zone_name))
        if not weeks:
            raise InvalidParameterError(
                f"a series repeats until a day on or after its first, got {until.isoformat()}"
            )
        if len(weeks) > MAX_SERIES_WEEKS:
            raise InvalidParameterError(f"a series books at most {MAX_SERIES_WEEKS} weeks")
        series = secrets.token_hex(8)
        now = self._clock.now()
        with self._db.write() as session:
            row = course_named(session, course, lock=True)
            require_member(session, row, who, Role.TEACHER, "book rigs for it")
            require_open(row, "book rigs for it")
            self._bookings.lock(session, wanted)
            free: list[tuple[datetime, datetime]] = []
            clashes: list[dict[str, object]] = []
            for a, b in weeks:
                try:
                    refuse_clash(session, wanted, a, b, exclude=None)
                except BookingClashError as clash:
                    clashes.append(
                        {"startsAt": a.isoformat(), "endsAt": b.isoformat(), "slot": clash.slot}
                    )
                else:
                    free.append((a, b))
            if clashes and not skip_clashes:
                raise BookingSeriesClashError(
                    f"{len(clashes)} of the {len(weeks)} weeks overlap other bookings "
                    f"(the first on {clashes[0]['startsAt']}); nothing was booked",
                    clashes,
                )
            booked = [
                _insert(session, row.id, wanted, a, b, who, now, note=note.strip(), series=series)
                for a, b in free
            ]
            infos = [booking_info(session, b, who, teacher=True) for b in booked]
            return SeriesResult(series, zone_name, infos, clashes)

    def _course_rigs(self, session: Session, course_id: int) -> list[str]:
        chosen = sorted(
            session.scalars(select(CourseRig.rig_id).where(CourseRig.course_id == course_id))
        )
        known = [rig.id for rig in self._config.rigs]
        return [r for r in chosen if r in known] if chosen else known


def _require(who: Principal, action: Action) -> None:
    if scope_of(who, action) is Scope.NONE:
        reach = (Scope.LAB, Scope.TAUGHT, Scope.SELF)
        raise AccessDeniedError(f"only {who_may(action, reach)} may {action}")


def _used(session: Session, course_id: int, user_id: int, week: tuple[datetime, datetime]) -> int:
    """Minutes of ``user_id``'s own bookings of the course starting in ``week`` (start, end)."""
    rows = session.execute(
        select(Booking.starts_at, Booking.ends_at).where(
            Booking.course_id == course_id,
            Booking.booked_for == user_id,
            Booking.starts_at >= week[0],
            Booking.starts_at < week[1],
        )
    ).all()
    return round(sum((b - a).total_seconds() for a, b in rows) / 60)


def _insert(
    session: Session,
    course_id: int,
    rigs: list[str],
    start: datetime,
    end: datetime,
    who: Principal,
    now: datetime,
    *,
    note: str = "",
    booked_for: int | None = None,
    series: str | None = None,
) -> Booking:
    booking = Booking(
        course_id=course_id,
        starts_at=start,
        ends_at=end,
        note=note,
        created_by=who.username,
        created_at=now,
        updated_at=now,
        booked_for=booked_for,
        series=series,
    )
    session.add(booking)
    session.flush()
    session.add_all(BookingRig(booking_id=booking.id, rig_id=rig) for rig in rigs)
    session.flush()
    return booking
