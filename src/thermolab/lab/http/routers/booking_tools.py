"""Routes of the booking tools: quotas and students' own bookings, weekly series,
calendar feeds and e-mail reminders (issue #24, item 7).

Each asks the policy through its service (:mod:`thermolab.lab.classes.booking_tools`,
:mod:`~thermolab.lab.classes.calendar_feeds`, :mod:`~thermolab.lab.classes.reminders`).
The one route without a login is a feed's secret address, ``GET
/api/calendar/{token}.ics``: a calendar application has no cookie, and the
address is the credential (revocable; the lab keeps its SHA-256 only).
"""

from __future__ import annotations

from datetime import date, datetime
from typing import Annotated

from fastapi import APIRouter, Path, Request, Response, status
from pydantic import Field

from thermolab.lab.classes.booking_tools import MAX_QUOTA_MINUTES, OwnBookingCourse
from thermolab.lab.classes.calendar_feeds import FeedInfo
from thermolab.lab.classes.reminders import MAX_MINUTES_BEFORE, ReminderSettings
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import AUTHENTICATED, MAX_ROW_ID, LabDep, UserDep, documented_errors
from thermolab.lab.http.errors import request_language
from thermolab.lab.http.routers.bookings import BookingOut, Instant
from thermolab.lab.http.routers.courses import CourseName

__all__ = ["public_router", "router"]

router = APIRouter(**AUTHENTICATED)
public_router = APIRouter()

FeedId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="the feed's number")]
_Rig = Annotated[str, Field(min_length=1, max_length=64)]


class QuotaIn(In):
    """How long each student of the course may book for themselves a week."""

    minutes_per_week: Annotated[int, Field(ge=0, le=MAX_QUOTA_MINUTES)]


class QuotaOut(Out):
    """A course's weekly quota of students' own bookings (0: students book nothing)."""

    course: str
    minutes_per_week: int


class OwnBookingIn(In):
    """A free slot of one of the course's rigs, for the student themselves."""

    rig: _Rig
    starts_at: Instant
    ends_at: Instant


class OwnCourseOut(Out):
    """A course the reader may book for themselves in, and their use of this week's quota."""

    course: str
    title: str
    minutes_per_week: int
    used_minutes: int = Field(description="the reader's own bookings starting this week (UTC)")
    week_starts_at: datetime
    rigs: list[str]

    @classmethod
    def of(cls, c: OwnBookingCourse) -> OwnCourseOut:
        """Build from a :class:`~thermolab.lab.classes.booking_tools.OwnBookingCourse`."""
        return cls(
            course=c.course,
            title=c.title,
            minutes_per_week=c.minutes_per_week,
            used_minutes=c.used_minutes,
            week_starts_at=c.week_starts_at,
            rigs=list(c.rigs),
        )


class SeriesIn(In):
    """The same slot every week until a day."""

    course: Annotated[str, Field(min_length=1, max_length=64)]
    rigs: Annotated[list[_Rig], Field(min_length=1, max_length=20)]
    starts_at: Instant
    ends_at: Instant
    until: Annotated[date, Field(strict=False, description="the last day (inclusive), ISO 8601")]
    note: Annotated[str, Field(max_length=200)] = ""
    longer: bool = False
    skip_clashes: bool = Field(
        default=False,
        description="book the weeks that are free and list the others (false: a clash books "
        "nothing)",
    )
    zone: Annotated[str, Field(min_length=1, max_length=64)] | None = Field(
        default=None,
        description="the IANA time zone whose wall-clock time the weeks keep across changes "
        "of daylight saving, and of the day until (e.g. America/New_York; left out: the lab's "
        "time zone); an unknown zone is a 422 time_zone_unknown",
    )


class SeriesOut(Out):
    """The weeks booked, and those left out because another booking was in the way."""

    series: str
    zone: str = Field(description="the time zone whose wall-clock time the weeks keep")
    booked: list[BookingOut]
    skipped: list[dict[str, object]]


class FeedIn(In):
    """A feed of every course of the reader's, or of one."""

    course: Annotated[str, Field(min_length=1, max_length=64)] | None = None


class FeedOut(Out):
    """A calendar feed (its address only when just made)."""

    id: int
    course: str | None
    created_at: datetime
    last_read_at: datetime | None
    url: str | None = Field(default=None, description="the secret address, shown once")

    @classmethod
    def of(cls, f: FeedInfo, url: str | None = None) -> FeedOut:
        """Build from a :class:`~thermolab.lab.classes.calendar_feeds.FeedInfo`."""
        return cls(
            id=f.id,
            course=f.course,
            created_at=f.created_at,
            last_read_at=f.last_read_at,
            url=url,
        )


class RemindersIn(In):
    """Where, and how many minutes before a booking, to send a reminder."""

    email: Annotated[str, Field(min_length=3, max_length=254)]
    minutes_before: Annotated[int, Field(ge=1, le=MAX_MINUTES_BEFORE)]


class RemindersOut(Out):
    """The reader's reminders; ``available`` is false when the lab has no mail server."""

    available: bool
    email: str | None
    minutes_before: int | None

    @classmethod
    def of(cls, r: ReminderSettings) -> RemindersOut:
        """Build from :class:`~thermolab.lab.classes.reminders.ReminderSettings`."""
        return cls(available=r.available, email=r.email, minutes_before=r.minutes_before)


@router.get(
    "/courses/{course}/booking-quota",
    response_model=QuotaOut,
    tags=["bookings"],
    summary="A course's quota of students' own bookings",
    responses=documented_errors(403, 404),
)
def get_quota(course: CourseName, who: UserDep, lab: LabDep) -> QuotaOut:
    """Minutes a week each student may book for themselves (the course's teachers)."""
    return QuotaOut(course=course, minutes_per_week=lab.booking_tools.quota(who, course))


@router.put(
    "/courses/{course}/booking-quota",
    response_model=QuotaOut,
    tags=["bookings"],
    summary="Set a course's quota of students' own bookings",
    responses=documented_errors(403, 404, 409, 422),
)
def put_quota(course: CourseName, body: QuotaIn, who: UserDep, lab: LabDep) -> QuotaOut:
    """0 lets students book nothing; up to a week's minutes (the course's teachers)."""
    minutes = lab.booking_tools.set_quota(who, course, body.minutes_per_week)
    return QuotaOut(course=course, minutes_per_week=minutes)


@router.get(
    "/own-bookings",
    response_model=list[OwnCourseOut],
    tags=["bookings"],
    summary="Where you may book for yourself",
)
def own_courses(who: UserDep, lab: LabDep) -> list[OwnCourseOut]:
    """The reader's courses that let students book, with this week's use (students)."""
    return [OwnCourseOut.of(c) for c in lab.booking_tools.own_courses(who)]


@router.post(
    "/courses/{course}/own-bookings",
    response_model=BookingOut,
    status_code=status.HTTP_201_CREATED,
    tags=["bookings"],
    summary="Book a free slot for yourself",
    responses=documented_errors(403, 404, 409, 422),
)
def book_own(course: CourseName, body: OwnBookingIn, who: UserDep, lab: LabDep) -> BookingOut:
    """A student books one of the course's rigs within its weekly quota (409
    ``booking_quota_exceeded`` past it, ``booking_clash`` when not free)."""
    info = lab.booking_tools.book_own(who, course, body.rig, body.starts_at, body.ends_at)
    return BookingOut.of(info)


@router.post(
    "/booking-series",
    response_model=SeriesOut,
    status_code=status.HTTP_201_CREATED,
    tags=["bookings"],
    summary="Book a slot every week",
    responses=documented_errors(403, 404, 409, 422),
)
def book_series(body: SeriesIn, who: UserDep, lab: LabDep) -> SeriesOut:
    """Each week until ``until`` (teachers), at the first slot's wall-clock time in ``zone``
    (default: the lab's); 409 ``booking_series_clash`` lists the weeks in the way unless
    ``skipClashes``; 422 ``time_zone_unknown`` for a zone that is not an IANA name."""
    result = lab.booking_tools.book_series(
        who,
        body.course,
        body.rigs,
        body.starts_at,
        body.ends_at,
        body.until,
        note=body.note,
        longer=body.longer,
        skip_clashes=body.skip_clashes,
        zone=body.zone,
    )
    return SeriesOut(
        series=result.series,
        zone=result.zone,
        booked=[BookingOut.of(b) for b in result.booked],
        skipped=result.skipped,
    )


@router.get(
    "/calendar-feeds", response_model=list[FeedOut], tags=["bookings"], summary="Your feeds"
)
def list_feeds(who: UserDep, lab: LabDep) -> list[FeedOut]:
    """The reader's calendar feeds (never their addresses)."""
    return [FeedOut.of(f) for f in lab.calendar_feeds.list(who)]


@router.post(
    "/calendar-feeds",
    response_model=FeedOut,
    status_code=status.HTTP_201_CREATED,
    tags=["bookings"],
    summary="A new calendar feed",
    responses=documented_errors(403, 404, 422),
)
def create_feed(body: FeedIn, request: Request, who: UserDep, lab: LabDep) -> FeedOut:
    """A secret iCalendar address of the reader's bookings (one course's, or all): shown once."""
    made = lab.calendar_feeds.create(who, body.course)
    url = str(request.url_for("calendar_feed", token=f"{made.token}.ics"))
    return FeedOut.of(made.feed, url)


@router.delete(
    "/calendar-feeds/{feed_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["bookings"],
    summary="Revoke a calendar feed",
    responses=documented_errors(404),
)
def revoke_feed(feed_id: FeedId, who: UserDep, lab: LabDep) -> Response:
    """Its address answers 404 from now on."""
    lab.calendar_feeds.revoke(who, feed_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@public_router.get(
    "/calendar/{token}",
    name="calendar_feed",
    tags=["bookings"],
    summary="A calendar feed (iCalendar)",
    response_class=Response,
    responses={200: {"content": {"text/calendar": {}}}, **documented_errors(404)},
)
def calendar_feed(
    token: Annotated[str, Path(min_length=20, max_length=64, pattern=r"^[A-Za-z0-9_-]+\.ics$")],
    lab: LabDep,
) -> Response:
    """The bookings of the feed's owner as RFC 5545 (no login: the address is the secret)."""
    body = lab.calendar_feeds.ics(token.removesuffix(".ics"))
    return Response(
        body,
        media_type="text/calendar; charset=utf-8",
        headers={"Cache-Control": "private, max-age=300"},
    )


@router.get("/reminders", response_model=RemindersOut, tags=["bookings"], summary="Your reminders")
def get_reminders(who: UserDep, lab: LabDep) -> RemindersOut:
    """Where the reader's booking reminders go, and whether the lab can send any."""
    return RemindersOut.of(lab.reminders.settings(who))


@router.put(
    "/reminders",
    response_model=RemindersOut,
    tags=["bookings"],
    summary="Set your reminders",
    responses=documented_errors(422),
)
def put_reminders(body: RemindersIn, request: Request, who: UserDep, lab: LabDep) -> RemindersOut:
    """An e-mail this many minutes before each booking of the reader's, in the page's
    language (422 without a mail server)."""
    language = request_language(request.headers, request.cookies)
    settings = lab.reminders.subscribe(who, body.email, body.minutes_before, language)
    return RemindersOut.of(settings)


@router.delete(
    "/reminders",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["bookings"],
    summary="Stop your reminders",
    responses=documented_errors(404),
)
def delete_reminders(who: UserDep, lab: LabDep) -> Response:
    """No more reminders; the address is forgotten."""
    lab.reminders.unsubscribe(who)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
