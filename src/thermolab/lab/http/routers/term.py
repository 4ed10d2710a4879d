"""Routes of the end of a term: close, reopen, copy to the next term, remove last term's students.

A closed course answers every change with 409 ``course_closed``; reads and
exports go on. ``GET .../leavers`` lists the students a removal would take (a
dry run); ``POST .../purge-students`` takes that list back, so that nobody is
removed whom the administrator has not seen.
"""

from __future__ import annotations

import secrets
from datetime import date, datetime
from typing import Annotated, Literal

from fastapi import APIRouter, Request, status
from pydantic import Field, model_validator

from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.security import default_password_hasher
from thermolab.lab.audit.log import AuditAction
from thermolab.lab.classes.term import MAX_SHIFT_DAYS, CopyReport
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    LabDep,
    UserDep,
    audit,
    client_address,
    documented_errors,
)
from thermolab.lab.http.routers.assignments import AssignmentId, AssignmentOut
from thermolab.lab.http.routers.courses import CourseName, CourseOut

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


class ClosedCourseOut(CourseOut):
    """The closed course, and how many of its bookings the close cancelled."""

    released_bookings: int = Field(
        description="bookings that had not begun, cancelled so that other courses may book "
        "those rigs (a reopen does not bring them back)"
    )


class CopyIn(In):
    """The next term's course: its name, a title (default: the old one's), and its dates.

    Exactly one of ``shift_days`` (move every date by so many days) and
    ``starts`` (the new term's first day: the old course's first booked day,
    else the day it was created, moves there).
    """

    name: Annotated[str, Field(min_length=1, max_length=64)]
    title: Annotated[str | None, Field(min_length=1, max_length=200)] = None
    shift_days: Annotated[int | None, Field(ge=-MAX_SHIFT_DAYS, le=MAX_SHIFT_DAYS)] = None
    # JSON has no date type: an ISO 8601 day (strict bodies take no strings otherwise).
    starts: Annotated[date | None, Field(strict=False, description="YYYY-MM-DD")] = None

    @model_validator(mode="after")
    def _one_way_to_date(self) -> CopyIn:
        if (self.shift_days is None) == (self.starts is None):
            raise ValueError("give exactly one of shiftDays and starts")
        return self


class SkippedSlotOut(Out):
    """A booking of the old course the copy does not have, and why."""

    starts_at: datetime
    ends_at: datetime
    reason: str


class CopyOut(Out):
    """The copy: the new course, how far its dates moved, what it got and what it did not."""

    course: CourseOut
    shift_days: int
    assignments: int = Field(description="assignments copied, as drafts")
    bookings: int = Field(description="bookings made at the shifted dates")
    skipped_bookings: list[SkippedSlotOut]


class LeaverOut(Out):
    """A student a removal would take: in this closed course and in no open one."""

    username: str
    display_name: str | None


class PurgeIn(In):
    """The students shown by ``GET .../leavers`` (all of them) and what becomes of their runs."""

    students: Annotated[
        list[Annotated[str, Field(min_length=1, max_length=64)]], Field(max_length=5000)
    ]
    runs: Literal["keep", "delete"] = Field(
        description="keep: under a pseudonym, for the class's statistics; delete: with them"
    )


class PurgeOut(Out):
    """The pseudonyms the removed students' kept rows carry, and who was left and why."""

    removed: list[str]
    skipped: dict[str, str]


@router.post(
    "/courses/{course}/close",
    response_model=ClosedCourseOut,
    tags=["courses"],
    summary="Close a course for the term",
    responses=documented_errors(403, 404, 409, 422),
)
def close_course(
    course: CourseName, who: UserDep, lab: LabDep, request: Request
) -> ClosedCourseOut:
    """Make the course read-only: reads and exports go on, every change is 409 ``course_closed``.

    Its bookings that have not begun are cancelled (``releasedBookings``
    says how many), so that other courses may book those rigs; a slot under
    way stays to its end. Its teachers or an administrator; only an
    administrator reopens it, without the cancelled bookings.
    """
    lab.authorize.require_course(who, Action.COURSE_CLOSE, course)
    released = lab.term.close(course, who.username)
    audit(lab, who, request, AuditAction.COURSE_CLOSED, course, released_bookings=released)
    shown = CourseOut.of(lab.courses.get(course))
    return ClosedCourseOut(**dict(shown), released_bookings=released)


@router.post(
    "/courses/{course}/reopen",
    response_model=CourseOut,
    tags=["courses"],
    summary="Reopen a closed course",
    responses=documented_errors(403, 404, 409, 422),
)
def reopen_course(course: CourseName, who: UserDep, lab: LabDep, request: Request) -> CourseOut:
    """Open a closed course again (lab administrators)."""
    lab.authorize.require_lab(who, Action.COURSE_REOPEN)
    lab.term.reopen(course)
    audit(lab, who, request, AuditAction.COURSE_REOPENED, course)
    return CourseOut.of(lab.courses.get(course))


@router.post(
    "/courses/{course}/copy",
    response_model=CopyOut,
    status_code=status.HTTP_201_CREATED,
    tags=["courses"],
    summary="Copy a course to the next term",
    responses=documented_errors(403, 404, 409, 422),
)
def copy_course(
    course: CourseName, body: CopyIn, who: UserDep, lab: LabDep, request: Request
) -> CopyOut:
    """Make the next term's course from this one; its only teacher is whoever copies it.

    It gets the rigs, the limits, the assignments as drafts (deadlines
    shifted) and the bookings at the shifted dates (one that is over or
    clashes is left out and listed); no students, runs, hand-ins or marks.
    A taken name is 409 ``conflict``. A closed course copies too.
    """
    lab.authorize.require_course(who, Action.COURSE_COPY, course)
    lab.authorize.require(who, Action.COURSE_CREATE)
    shift = body.shift_days
    if shift is None:
        assert body.starts is not None  # the body's validator wants one of them
        shift = lab.term.shift_for(course, body.starts)
    report = lab.term.copy(course, body.name, body.title, who, shift)
    audit(
        lab,
        who,
        request,
        AuditAction.COURSE_COPIED,
        report.course,
        source=course,
        shift_days=report.shift_days,
    )
    return _copy_out(report, CourseOut.of(lab.courses.get(report.course)))


@router.get(
    "/courses/{course}/leavers",
    response_model=list[LeaverOut],
    tags=["courses"],
    summary="Students a removal would take (dry run)",
    responses=documented_errors(403, 404, 409, 422),
)
def leavers(course: CourseName, who: UserDep, lab: LabDep) -> list[LeaverOut]:
    """The students of this closed course who are in no open course (lab administrators)."""
    lab.authorize.require_lab(who, Action.COURSE_PURGE_STUDENTS)
    return [
        LeaverOut(username=p.username, display_name=p.display_name)
        for p in lab.term.leavers(course)
    ]


@router.post(
    "/courses/{course}/purge-students",
    response_model=PurgeOut,
    tags=["courses"],
    summary="Remove a closed course's students",
    responses=documented_errors(403, 404, 409, 422),
)
def purge_students(
    course: CourseName, body: PurgeIn, who: UserDep, lab: LabDep, request: Request
) -> PurgeOut:
    """Remove the students ``GET .../leavers`` listed, each as ``POST .../forget`` does.

    ``students`` must be that list as it is now (409 otherwise: nobody is
    removed unseen). One at a rig's controls or waiting is left, in ``skipped``.
    """
    lab.authorize.require_lab(who, Action.COURSE_PURGE_STUDENTS)
    lab.authorize.require_lab(who, Action.ACCOUNT_FORGET)
    unknown = default_password_hasher().hash(secrets.token_urlsafe(32))
    written = lab.audit.forgotten(who.username, address=client_address(request), runs=body.runs)
    report = lab.term.purge(course, body.students, body.runs, unknown, audit=written)
    lab.names.forget()
    audit(
        lab,
        who,
        request,
        AuditAction.COURSE_STUDENTS_PURGED,
        course,
        runs=body.runs,
        removed=report.removed,
        skipped=len(report.skipped),
    )
    return PurgeOut(removed=report.removed, skipped=report.skipped)


@router.post(
    "/assignments/{assignment_id}/publish",
    response_model=AssignmentOut,
    tags=["assignments"],
    summary="Publish a draft assignment",
    responses=documented_errors(403, 404, 409, 422),
)
def publish(
    assignment_id: AssignmentId, who: UserDep, lab: LabDep, request: Request
) -> AssignmentOut:
    """Let the course's students see a draft (copied) assignment and hand in (its teachers)."""
    lab.term.publish(assignment_id, who)
    published = AssignmentOut.of(lab.assignments.get(assignment_id, who))
    audit(
        lab, who, request, AuditAction.ASSIGNMENT_PUBLISHED, f"{published.course} #{assignment_id}"
    )
    return published


def _copy_out(report: CopyReport, course: CourseOut) -> CopyOut:
    return CopyOut(
        course=course,
        shift_days=report.shift_days,
        assignments=report.assignments,
        bookings=report.bookings,
        skipped_bookings=[
            SkippedSlotOut(starts_at=s.starts_at, ends_at=s.ends_at, reason=s.reason)
            for s in report.skipped
        ],
    )
