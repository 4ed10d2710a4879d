"""Routes of courses (teachers), self-enrolment with a code (anyone), password resets (teachers).

A class list is uploaded as the raw CSV file (``PUT /api/courses/{course}/roster``,
any content type): its bytes are judged as they are, so a file that is not
UTF-8 is reported by line instead of being mangled on the way.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

import anyio.to_thread
from fastapi import APIRouter, Path, Request, status
from pydantic import Field

from thermolab.errors import (
    AccessDeniedError,
    ClassListError,
    ClassListProblem,
    WrongEnrolCodeError,
)
from thermolab.lab.accounts.names import MAX_DISPLAY_NAME
from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.security import (
    MAX_PASSWORD_LENGTH,
    MIN_PASSWORD_LENGTH,
    AuthenticationError,
    normalize_username,
)
from thermolab.lab.audit.log import AuditAction
from thermolab.lab.classes.class_list import MAX_CLASS_LIST_BYTES
from thermolab.lab.classes.courses import CourseInfo, ImportReport
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    LabDep,
    UserDep,
    Username,
    audit,
    client_address,
    documented_errors,
)

__all__ = ["router"]

# Every route needs a login but self-enrolment, which is on ``router`` itself.
router = APIRouter()
_teachers = APIRouter(**AUTHENTICATED)

CourseName = Annotated[
    str,
    Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"),
]


class NewCourseIn(In):
    """A new course: a short name (the URL's) and a title."""

    name: Annotated[str, Field(min_length=1, max_length=64)]
    title: Annotated[str, Field(min_length=1, max_length=200)]


class CourseRigsIn(In):
    """The rigs a course's students may use (empty: every rig)."""

    rigs: Annotated[list[Annotated[str, Field(min_length=1, max_length=64)]], Field(max_length=100)]


class MemberOut(Out):
    """A person of a course."""

    username: str
    display_name: str | None
    role: Literal["student", "teacher", "assistant"]
    must_change_password: bool


class CourseOut(Out):
    """A course; ``members`` is filled when one course is asked for."""

    name: str
    title: str
    enrol_code: str
    created_at: datetime
    rigs: list[str]
    members: list[MemberOut]
    closed_at: datetime | None = Field(
        None, description="when the course was closed for the term (null: open)"
    )
    closed_by: str | None = Field(None, description="who closed it")

    @classmethod
    def of(cls, course: CourseInfo) -> CourseOut:
        """Build from a :class:`~thermolab.lab.classes.courses.CourseInfo`."""
        return cls(
            name=course.name,
            title=course.title,
            enrol_code=course.enrol_code,
            created_at=course.created_at,
            rigs=list(course.rigs),
            members=[
                MemberOut(
                    username=m.username,
                    display_name=m.display_name,
                    role=m.role.value,
                    must_change_password=m.must_change_password,
                )
                for m in course.members
            ],
            closed_at=course.closed_at,
            closed_by=course.closed_by,
        )


class ImportOut(Out):
    """What a class list changed; ``created`` maps each new login to its one-time password."""

    created: dict[str, str]
    updated: list[str]
    unchanged: list[str]
    encoding: str = Field(
        "UTF-8",
        description="how the file's bytes were read: UTF-8, UTF-8 with BOM, UTF-16 or Windows-1252",
    )

    @classmethod
    def of(cls, report: ImportReport) -> ImportOut:
        """Build from an :class:`~thermolab.lab.classes.courses.ImportReport`."""
        return cls(
            created=report.created,
            updated=report.updated,
            unchanged=report.unchanged,
            encoding=report.encoding,
        )


class EnrolCodeOut(Out):
    """A course's new enrolment code."""

    enrol_code: str


class EnrolIn(In):
    """Self-enrolment: the course's code and the new account."""

    code: Annotated[str, Field(min_length=1, max_length=32)]
    username: Annotated[str, Field(min_length=1, max_length=64)]
    display_name: Annotated[str, Field(min_length=1, max_length=MAX_DISPLAY_NAME)]
    password: Annotated[str, Field(min_length=MIN_PASSWORD_LENGTH, max_length=MAX_PASSWORD_LENGTH)]


class EnrolledOut(Out):
    """The account self-enrolment created."""

    username: str
    display_name: str | None


class ResetIn(In):
    """A teacher's own current password (re-authentication)."""

    current_password: Annotated[str, Field(min_length=1, max_length=MAX_PASSWORD_LENGTH)]


class ResetOut(Out):
    """The student's one-time password, shown once."""

    temporary_password: str


@_teachers.get(
    "/courses",
    response_model=list[CourseOut],
    tags=["courses"],
    summary="All courses",
    responses=documented_errors(403),
)
def list_courses(who: UserDep, lab: LabDep) -> list[CourseOut]:
    """The courses you teach (every course for an administrator), without rosters."""
    lab.authorize.require(who, Action.COURSES_READ)
    taught = lab.authorize.taught(who, Action.COURSES_READ)
    return [CourseOut.of(c) for c in lab.courses.list() if taught is None or c.name in taught]


@_teachers.post(
    "/courses",
    response_model=CourseOut,
    status_code=status.HTTP_201_CREATED,
    tags=["courses"],
    summary="Create a course",
    responses=documented_errors(403, 409, 422),
)
def create_course(body: NewCourseIn, who: UserDep, lab: LabDep, request: Request) -> CourseOut:
    """Create a course; its creator is its first teacher (teachers only)."""
    lab.authorize.require(who, Action.COURSE_CREATE)
    created = CourseOut.of(lab.courses.create(body.name, body.title, who.username))
    audit(lab, who, request, AuditAction.COURSE_CREATED, created.name)
    return created


@_teachers.get(
    "/courses/{course}",
    response_model=CourseOut,
    tags=["courses"],
    summary="A course with its roster",
    responses=documented_errors(403, 404, 422),
)
def get_course(course: CourseName, who: UserDep, lab: LabDep) -> CourseOut:
    """A course with its teachers and students (its teachers, administrators)."""
    lab.authorize.require_course(who, Action.COURSE_READ, course)
    return CourseOut.of(lab.courses.get(course))


@_teachers.put(
    "/courses/{course}/roster",
    response_model=ImportOut,
    tags=["courses"],
    summary="Upload a class list (CSV)",
    responses=documented_errors(403, 404, 409, 413, 422),
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {"text/csv": {"schema": {"type": "string", "format": "binary"}}},
        }
    },
)
async def upload_roster(
    course: CourseName, request: Request, who: UserDep, lab: LabDep
) -> ImportOut:
    """Add or update a course's students from a CSV class list, all or nothing.

    A login column and a name column, headed in English, Portuguese or
    Spanish (``username;display_name``, ``matrícula;nome``, ``usuario;nombre``);
    UTF-8 (with or without BOM), UTF-16 with BOM or Windows-1252; the answer's
    ``encoding`` says which was read. A 422 ``class_list_invalid`` lists each bad
    line in ``errors`` (``loc`` = ``["file", line]``, ``type`` its stable code,
    ``params`` its values, ``message`` its sentence in the reader's language) and
    nothing changes.
    """
    lab.authorize.require_course(who, Action.COURSE_ROSTER, course)
    data = b""
    async for chunk in request.stream():
        data += chunk
        if len(data) > MAX_CLASS_LIST_BYTES:
            raise ClassListError(
                [ClassListProblem.of(0, "class_list.too_large", limit=MAX_CLASS_LIST_BYTES)]
            )
    report = await anyio.to_thread.run_sync(lab.courses.import_class_list, course, data)
    lab.names.forget()  # a re-upload may have renamed people
    audit(
        lab,
        who,
        request,
        AuditAction.ROSTER_CHANGED,
        course,
        created=sorted(report.created),
        updated=report.updated,
    )
    return ImportOut.of(report)


@_teachers.post(
    "/courses/{course}/enrol-code",
    response_model=EnrolCodeOut,
    tags=["courses"],
    summary="A new enrolment code",
    responses=documented_errors(403, 404, 422),
)
def rotate_code(course: CourseName, who: UserDep, lab: LabDep, request: Request) -> EnrolCodeOut:
    """Replace the course's enrolment code; the old one stops working (its teachers)."""
    lab.authorize.require_course(who, Action.COURSE_ENROL_CODE, course)
    code = lab.courses.rotate_code(course)
    audit(lab, who, request, AuditAction.ENROL_CODE_ROTATED, course)
    return EnrolCodeOut(enrol_code=code)


@_teachers.put(
    "/courses/{course}/rigs",
    response_model=CourseOut,
    tags=["courses"],
    summary="The rigs a course may use",
    responses=documented_errors(403, 404, 422),
)
def set_rigs(
    course: CourseName, body: CourseRigsIn, who: UserDep, lab: LabDep, request: Request
) -> CourseOut:
    """Set the rigs the course's students may use; an empty list means every rig."""
    lab.authorize.require_course(who, Action.COURSE_RIGS, course)
    known = {rig.id for rig in lab.config.rigs}
    changed = CourseOut.of(lab.courses.set_rigs(course, body.rigs, known))
    audit(lab, who, request, AuditAction.COURSE_RIGS_SET, course, rigs=changed.rigs)
    return changed


@_teachers.put(
    "/courses/{course}/assistants/{username}",
    response_model=CourseOut,
    tags=["courses"],
    summary="Make someone a teaching assistant of a course",
    responses=documented_errors(403, 404, 409, 422),
)
def add_assistant(
    course: CourseName, username: Username, who: UserDep, lab: LabDep, request: Request
) -> CourseOut:
    """Give an account (a student's or a teacher's) an assistant's place in the course.

    An assistant sees the roster, assignments, hand-ins, grades and
    analytics, and changes none of them (see the teacher's guide). 409 for a
    student or teacher of the course. Its teachers, administrators; logged.
    """
    lab.authorize.require_course(who, Action.COURSE_ASSISTANTS, course)
    name = lab.assistants.add(course, username)
    audit(lab, who, request, AuditAction.ASSISTANT_ADDED, course, username=name)
    return CourseOut.of(lab.courses.get(course))


@_teachers.delete(
    "/courses/{course}/assistants/{username}",
    response_model=CourseOut,
    tags=["courses"],
    summary="Take a teaching assistant's place away",
    responses=documented_errors(403, 404, 409, 422),
)
def remove_assistant(
    course: CourseName, username: Username, who: UserDep, lab: LabDep, request: Request
) -> CourseOut:
    """Remove an assistant from the course (their account stays). Its teachers; logged."""
    lab.authorize.require_course(who, Action.COURSE_ASSISTANTS, course)
    name = lab.assistants.remove(course, username)
    audit(lab, who, request, AuditAction.ASSISTANT_REMOVED, course, username=name)
    return CourseOut.of(lab.courses.get(course))


@router.post(
    "/enrol",
    response_model=EnrolledOut,
    status_code=status.HTTP_201_CREATED,
    tags=["courses"],
    summary="Enrol with a course code",
    responses=documented_errors(403, 409, 422, 429),
)
def enrol(body: EnrolIn, request: Request, lab: LabDep) -> EnrolledOut:
    """Create a student account in the course whose code this is (no login needed).

    Attempts are throttled like logins, per (code, client address) and per
    address, so codes cannot be guessed quickly; a wrong code is 403
    ``enrol_code_wrong``.
    """
    address = request.client.host if request.client is not None else "unknown"
    key = f"enrol:{body.code.strip().upper()}"
    lab.throttle.check(key, address)
    try:
        user = lab.courses.enrol(body.code, body.username, body.display_name, body.password)
        lab.names.forget()
    except WrongEnrolCodeError:
        lab.throttle.record(key, address, success=False)
        raise
    lab.throttle.record(key, address, success=True)
    return EnrolledOut(username=user.username, display_name=user.display_name)


@_teachers.post(
    "/users/{username}/password-reset",
    response_model=ResetOut,
    tags=["users"],
    summary="Reset a student's password",
    responses=documented_errors(403, 404, 422, 429),
)
def reset_password(
    username: Username, body: ResetIn, who: UserDep, lab: LabDep, request: Request
) -> ResetOut:
    """Give a student a one-time password, shown once; they must change it at next login.

    The teacher re-authenticates with their own current password (as for a
    password change); a script's API token cannot reset. Only a teacher of
    one of the student's courses, or an administrator, may reset (a teacher's
    password: administrators only). The student's logins end; the audit log
    records it.
    """
    lab.authorize.require(who, Action.PASSWORD_RESET)
    if who.token_id is not None:
        raise AccessDeniedError("an API token cannot reset passwords; log in with your password")
    if normalize_username(username) != who.username:
        lab.authorize.require_person(who, Action.PASSWORD_RESET, username)
    address = client_address(request)
    lab.throttle.check(who.username, address)
    try:
        lab.users.verify(who.username, body.current_password)
    except AuthenticationError:
        lab.throttle.record(who.username, address, success=False)
        raise AccessDeniedError("your current password is wrong") from None
    lab.throttle.record(who.username, address, success=True)
    if normalize_username(username) == who.username:
        raise AccessDeniedError("change your own password instead of resetting it")
    temporary = lab.courses.reset_password(username)
    audit(lab, who, request, AuditAction.PASSWORD_RESET, normalize_username(username))
    return ResetOut(temporary_password=temporary)


router.include_router(_teachers)
