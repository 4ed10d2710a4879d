"""Routes of bookings: teachers book courses' slots on rigs; everyone reads the calendar.

Instants travel as ISO 8601 with a zone (``2026-03-02T13:00:00Z``) and are
stored in UTC; the page shows them in the reader's zone and language. A slot
that overlaps another on a shared rig is a 409 ``booking_clash`` whose
``slot`` names the booking in the way (course, start, end, shared rigs).
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, Path, Query, Response, status
from pydantic import AwareDatetime, Field

from thermolab.errors import InvalidParameterError
from thermolab.lab.classes.bookings import BookingInfo, NextChance
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    MAX_ROW_ID,
    LabDep,
    RigId,
    RigQuery,
    UserDep,
    documented_errors,
)

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)

BookingId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="the booking's number")]
_INSTANT = r"^\d{4}-\d{2}-\d{2}T\d{2}:\d{2}(:\d{2}(\.\d{1,6})?)?(Z|[+-]\d{2}:\d{2})$"
# JSON has no time type: an instant is an ISO 8601 string (strict bodies take no strings
# for a datetime otherwise), with its zone.
Instant = Annotated[AwareDatetime, Field(strict=False, description="ISO 8601, with the zone")]
_DESCRIBED = "an ISO 8601 instant with its zone, e.g. 2026-03-02T13:00:00Z"
From = Annotated[
    str,
    Query(alias="from", min_length=16, max_length=32, pattern=_INSTANT, description=_DESCRIBED),
]
To = Annotated[
    str,
    Query(alias="to", min_length=16, max_length=32, pattern=_INSTANT, description=_DESCRIBED),
]


class BookingIn(In):
    """A course's slot on one or more rigs."""

    course: Annotated[str, Field(min_length=1, max_length=64)]
    rigs: Annotated[
        list[Annotated[str, Field(min_length=1, max_length=64)]], Field(min_length=1, max_length=20)
    ]
    starts_at: Instant
    ends_at: Instant
    note: Annotated[str, Field(max_length=200)] = ""
    longer: bool = Field(
        default=False, description="the slot is longer than a day on purpose (up to 7 days)"
    )


class BookingEditIn(In):
    """A booking's new time, rigs and note (its course stays)."""

    rigs: Annotated[
        list[Annotated[str, Field(min_length=1, max_length=64)]], Field(min_length=1, max_length=20)
    ]
    starts_at: Instant
    ends_at: Instant
    note: Annotated[str, Field(max_length=200)] = ""
    longer: bool = Field(
        default=False, description="the slot is longer than a day on purpose (up to 7 days)"
    )


class BookingOut(Out):
    """A booking as the reader sees it: ``course`` is null for another course's slot (students)."""

    id: int
    course: str | None
    course_title: str | None
    own: bool = Field(description="whether the reader is in the booking's course")
    rigs: list[str]
    starts_at: datetime
    ends_at: datetime
    note: str
    created_by: str | None
    self_booked: bool = Field(description="a student's own booking within the course's quota")
    mine: bool = Field(description="the reader booked it for themselves (and may cancel it)")
    series: str | None = Field(description="the weekly series it was booked with, if any")

    @classmethod
    def of(cls, b: BookingInfo) -> BookingOut:
        """Build from a :class:`~thermolab.lab.classes.bookings.BookingInfo`."""
        return cls(
            id=b.id,
            course=b.course,
            course_title=b.course_title,
            own=b.own,
            rigs=list(b.rigs),
            starts_at=b.starts_at,
            ends_at=b.ends_at,
            note=b.note,
            created_by=b.created_by,
            self_booked=b.self_booked,
            mine=b.mine,
            series=b.series,
        )


class NextChanceOut(Out):
    """When the reader may next take a rig's controls, by the bookings."""

    booked_now: BookingOut | None = Field(description="the slot going on, if any")
    free_from: datetime | None = Field(
        description="when another course's slot (or run of slots) ends; null: the reader may "
        "ask for control now"
    )
    next_own: BookingOut | None = Field(description="the next slot of one of the reader's courses")

    @classmethod
    def of(cls, n: NextChance) -> NextChanceOut:
        """Build from a :class:`~thermolab.lab.classes.bookings.NextChance`."""
        return cls(
            booked_now=None if n.booked_now is None else BookingOut.of(n.booked_now),
            free_from=n.free_from,
            next_own=None if n.next_own is None else BookingOut.of(n.next_own),
        )


def _instant(value: str, name: str) -> datetime:
    try:
        return datetime.fromisoformat(value)
    except ValueError:
        raise InvalidParameterError(
            f"{name} must be an ISO 8601 instant with its zone, got {value!r}"
        ) from None


@router.get(
    "/bookings",
    response_model=list[BookingOut],
    tags=["bookings"],
    summary="The calendar",
    responses=documented_errors(404, 422),
)
def calendar(
    who: UserDep,
    lab: LabDep,
    start: From,
    end: To,
    rig: RigQuery = None,
) -> list[BookingOut]:
    """Bookings that overlap ``[from, to)`` (at most 62 days), optionally of one rig.

    Students see their courses' slots named and the others' only as reserved.
    """
    bookings = lab.bookings.calendar(who, _instant(start, "from"), _instant(end, "to"), rig)
    return [BookingOut.of(b) for b in bookings]


@router.post(
    "/bookings",
    response_model=BookingOut,
    status_code=status.HTTP_201_CREATED,
    tags=["bookings"],
    summary="Book a slot",
    responses=documented_errors(403, 404, 409, 422),
)
def book(body: BookingIn, who: UserDep, lab: LabDep) -> BookingOut:
    """Book rigs for a course's slot (teachers); 409 ``booking_clash`` names the slot in the way."""
    info = lab.bookings.create(
        who, body.course, body.rigs, body.starts_at, body.ends_at, body.note, longer=body.longer
    )
    return BookingOut.of(info)


@router.put(
    "/bookings/{booking}",
    response_model=BookingOut,
    tags=["bookings"],
    summary="Edit a booking",
    responses=documented_errors(403, 404, 409, 422),
)
def edit(booking: BookingId, body: BookingEditIn, who: UserDep, lab: LabDep) -> BookingOut:
    """Move a booking or change its rigs (teachers); the same checks as booking."""
    info = lab.bookings.update(
        who, booking, body.rigs, body.starts_at, body.ends_at, body.note, longer=body.longer
    )
    return BookingOut.of(info)


@router.delete(
    "/bookings/{booking}",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["bookings"],
    summary="Cancel a booking",
    responses=documented_errors(403, 404, 422),
)
def cancel(booking: BookingId, who: UserDep, lab: LabDep) -> Response:
    """Cancel a booking (its course's teachers, or the student who booked it for themselves)."""
    lab.bookings.cancel(who, booking)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get(
    "/rigs/{rig_id}/next-chance",
    response_model=NextChanceOut,
    tags=["bookings"],
    summary="Your next chance at a rig",
    responses=documented_errors(404, 422),
)
def next_chance(rig_id: RigId, who: UserDep, lab: LabDep) -> NextChanceOut:
    """The slot going on, when the reader may queue again, and their course's next slot."""
    return NextChanceOut.of(lab.bookings.next_chance(who, rig_id))
