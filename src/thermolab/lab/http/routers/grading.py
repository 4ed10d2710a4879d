"""Routes of a teacher's grading tools: marks overridden, deadlines extended, lab groups.

``GET /api/assignments/{id}/standings`` is each student's standing on an
assignment (final and automatic mark, comment, own deadline, lab group) for
the course's teachers and assistants. Overriding a mark, extending a
deadline and forming or removing a lab group are the course's teachers'
(and administrators'); each is written to the audit log. A student reads
their own extension, override and group with the assignment
(``GET /api/assignments/{id}``).
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, Path, Request, Response, status
from pydantic import AwareDatetime, Field

from thermolab.lab.assignments import ExtensionInfo, GroupInfo, Standing
from thermolab.lab.assignments.marking import MARK_MAX
from thermolab.lab.assignments.overrides import MAX_COMMENT
from thermolab.lab.audit.log import AuditAction
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    MAX_ROW_ID,
    LabDep,
    UserDep,
    Username,
    audit,
    documented_errors,
)
from thermolab.lab.http.routers.assignments import AssignmentId
from thermolab.lab.http.routers.courses import CourseName

__all__ = ["ExtensionOut", "GroupOut", "OverrideOut", "router"]

router = APIRouter(**AUTHENTICATED)

GroupId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="the lab group's number")]
_Student = Annotated[str, Field(min_length=1, max_length=64)]


class OverrideIn(In):
    """A teacher's mark for a student (0 to 10) and the comment the student reads."""

    mark: Annotated[float, Field(ge=0, le=MARK_MAX, allow_inf_nan=False)]
    comment: Annotated[str, Field(min_length=1, max_length=MAX_COMMENT)]


class OverrideOut(Out):
    """A mark overridden: the final mark, the automatic one beside it, the comment."""

    student: str
    mark: float
    automatic_mark: float | None
    max: float
    comment: str
    set_by: str
    set_at: datetime


class ExtensionIn(In):
    """The student's own deadline (after the assignment's)."""

    deadline: Annotated[AwareDatetime, Field(strict=False)]


class ExtensionOut(Out):
    """A student's extended deadline."""

    assignment_id: int
    student: str
    deadline: datetime
    set_by: str
    set_at: datetime

    @classmethod
    def of(cls, e: ExtensionInfo) -> ExtensionOut:
        """Build from an :class:`~thermolab.lab.assignments.ExtensionInfo`."""
        return cls(
            assignment_id=e.assignment_id,
            student=e.student,
            deadline=e.deadline,
            set_by=e.set_by,
            set_at=e.set_at,
        )


class GroupMemberOut(Out):
    """A member of a lab group."""

    username: str
    display_name: str | None


class GroupIn(In):
    """A lab group: its name and its students' login names (2 to 12)."""

    name: Annotated[str, Field(min_length=1, max_length=64)]
    members: Annotated[list[_Student], Field(min_length=2, max_length=12)]


class GroupOut(Out):
    """A lab group of a course."""

    id: int
    course: str
    name: str
    members: list[GroupMemberOut]
    created_by: str
    created_at: datetime

    @classmethod
    def of(cls, g: GroupInfo) -> GroupOut:
        """Build from a :class:`~thermolab.lab.assignments.GroupInfo`."""
        return cls(
            id=g.id,
            course=g.course,
            name=g.name,
            members=[GroupMemberOut(username=u, display_name=d) for u, d in g.members],
            created_by=g.created_by,
            created_at=g.created_at,
        )


class StandingOut(Out):
    """A student's standing on an assignment.

    ``mark`` is the final mark (the override where there is one);
    ``automaticMark`` the lab's; ``comment`` the override's ("" if none);
    ``deadline`` the student's own (``extended``: by an extension).
    """

    student: str
    display_name: str | None
    state: str
    mark: float | None
    automatic_mark: float | None
    max: float
    comment: str
    overridden: bool
    late: bool
    submitted_at: datetime | None
    run_id: int | None
    deadline: datetime
    extended: bool
    group: str | None

    @classmethod
    def of(cls, s: Standing) -> StandingOut:
        """Build from a :class:`~thermolab.lab.assignments.Standing`."""
        g = s.grade
        return cls(
            student=g.student,
            display_name=g.display_name,
            state=g.state,
            mark=g.mark,
            automatic_mark=g.automatic_mark,
            max=g.max,
            comment=g.comment,
            overridden=g.comment != "",
            late=g.late,
            submitted_at=g.submitted_at,
            run_id=g.run_id,
            deadline=s.deadline,
            extended=s.extended,
            group=s.group,
        )


@router.get(
    "/assignments/{assignment_id}/standings",
    response_model=list[StandingOut],
    tags=["grading"],
    summary="Each student's standing on an assignment",
    responses=documented_errors(403, 404, 422),
)
def list_standings(assignment_id: AssignmentId, who: UserDep, lab: LabDep) -> list[StandingOut]:
    """Every student of the course: final and automatic mark, comment, deadline, lab group.

    The course's teachers and assistants.
    """
    return [StandingOut.of(s) for s in lab.assignments.standings(assignment_id, who)]


@router.put(
    "/assignments/{assignment_id}/overrides/{username}",
    response_model=OverrideOut,
    tags=["grading"],
    summary="Override a student's mark, with a comment",
    responses=documented_errors(403, 404, 409, 422),
)
def set_override(
    assignment_id: AssignmentId,
    username: Username,
    body: OverrideIn,
    who: UserDep,
    lab: LabDep,
    request: Request,
) -> OverrideOut:
    """Give the student a mark of your own, saying why; the automatic mark is kept beside it.

    The override stands over later hand-ins until it is removed; the LMS
    gets the final mark. 409 ``conflict``: the student handed nothing in.
    The course's teachers; logged.
    """
    made, grade = lab.assignments.overrides.set(
        assignment_id, who, username, body.mark, body.comment
    )
    audit(
        lab,
        who,
        request,
        AuditAction.MARK_OVERRIDDEN,
        f"{grade.course} #{assignment_id}",
        student=made.student,
        mark=made.mark,
        automatic_mark=grade.automatic_mark,
    )
    return OverrideOut(
        student=made.student,
        mark=made.mark,
        automatic_mark=grade.automatic_mark,
        max=made.max,
        comment=made.comment,
        set_by=made.set_by,
        set_at=made.set_at,
    )


@router.delete(
    "/assignments/{assignment_id}/overrides/{username}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    tags=["grading"],
    summary="Remove a student's overridden mark",
    responses=documented_errors(403, 404, 409, 422),
)
def remove_override(
    assignment_id: AssignmentId, username: Username, who: UserDep, lab: LabDep, request: Request
) -> Response:
    """The automatic mark is the final one again (none there: nothing changes). Logged."""
    grade = lab.assignments.overrides.remove(assignment_id, who, username)
    audit(
        lab,
        who,
        request,
        AuditAction.MARK_OVERRIDE_REMOVED,
        f"{grade.course} #{assignment_id}",
        student=grade.student,
    )
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.put(
    "/assignments/{assignment_id}/extensions/{username}",
    response_model=ExtensionOut,
    tags=["grading"],
    summary="Extend the deadline for one student",
    responses=documented_errors(403, 404, 409, 422),
)
def set_extension(
    assignment_id: AssignmentId,
    username: Username,
    body: ExtensionIn,
    who: UserDep,
    lab: LabDep,
    request: Request,
) -> ExtensionOut:
    """Let the student hand in until ``deadline`` (after the assignment's) without being late.

    Their hand-ins are flagged late again against the new deadline. The
    course's teachers; logged.
    """
    made = lab.assignments.extensions.set(assignment_id, who, username, body.deadline)
    audit(
        lab,
        who,
        request,
        AuditAction.DEADLINE_EXTENDED,
        f"{made.course} #{assignment_id}",
        student=made.student,
        deadline=made.deadline.isoformat(),
    )
    return ExtensionOut.of(made)


@router.delete(
    "/assignments/{assignment_id}/extensions/{username}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    tags=["grading"],
    summary="Take a student's extension back",
    responses=documented_errors(403, 404, 409, 422),
)
def remove_extension(
    assignment_id: AssignmentId, username: Username, who: UserDep, lab: LabDep, request: Request
) -> Response:
    """The assignment's deadline is the student's again (none there: nothing changes). Logged."""
    course = lab.assignments.extensions.remove(assignment_id, who, username)
    audit(
        lab,
        who,
        request,
        AuditAction.EXTENSION_REMOVED,
        f"{course} #{assignment_id}",
        student=username.lower(),
    )
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get(
    "/courses/{course}/groups",
    response_model=list[GroupOut],
    tags=["grading"],
    summary="A course's lab groups",
    responses=documented_errors(403, 404, 422),
)
def list_groups(course: CourseName, who: UserDep, lab: LabDep) -> list[GroupOut]:
    """The course's lab groups by name, with their members (its teachers and assistants)."""
    return [GroupOut.of(g) for g in lab.assignments.groups.list(course, who)]


@router.post(
    "/courses/{course}/groups",
    response_model=GroupOut,
    status_code=status.HTTP_201_CREATED,
    tags=["grading"],
    summary="Form a lab group",
    responses=documented_errors(403, 404, 409, 422),
)
def create_group(
    course: CourseName, body: GroupIn, who: UserDep, lab: LabDep, request: Request
) -> GroupOut:
    """Form a group of 2 to 12 students of the course who share a run and a hand-in.

    A student is in at most one group of a course (409 ``conflict`` names
    who is in one already). The course's teachers; logged.
    """
    made = lab.assignments.groups.create(course, who, body.name, body.members)
    audit(
        lab,
        who,
        request,
        AuditAction.GROUP_CREATED,
        made.course,
        group=made.name,
        members=[u for u, _ in made.members],
    )
    return GroupOut.of(made)


@router.delete(
    "/courses/{course}/groups/{group_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    tags=["grading"],
    summary="Remove a lab group",
    responses=documented_errors(403, 404, 409, 422),
)
def remove_group(
    course: CourseName, group_id: GroupId, who: UserDep, lab: LabDep, request: Request
) -> Response:
    """Remove the group; the hand-ins its members made stay. Logged."""
    gone = lab.assignments.groups.remove(course, who, group_id)
    audit(
        lab,
        who,
        request,
        AuditAction.GROUP_REMOVED,
        gone.course,
        group=gone.name,
        members=[u for u, _ in gone.members],
    )
    return Response(status_code=status.HTTP_204_NO_CONTENT)
