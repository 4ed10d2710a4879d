"""Routes of assignments: teachers set them and read the hand-ins, students hand in.

``GET /api/assignments`` lists the assignments of the caller's courses (a
student's own hand-ins with each); ``GET /api/courses/{course}/grades.csv``
is the grades export (teachers of the course; formula-safe cells).
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

import anyio.to_thread
from fastapi import APIRouter, Path, Request, Response, status
from pydantic import AwareDatetime, Field

from thermolab.ident.registry import METHOD_NAMES
from thermolab.lab.assignments import (
    Answers,
    AssignmentDraft,
    AssignmentInfo,
    SubmissionInfo,
    Tolerances,
    grades_csv,
)
from thermolab.lab.audit.log import AuditAction
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    MAX_ROW_ID,
    LabDep,
    SheetDep,
    UserDep,
    audit,
    documented_errors,
)
from thermolab.lab.http.routers.courses import CourseName

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)

AssignmentId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="the assignment's number")]
_Finite = Annotated[float, Field(allow_inf_nan=False)]
_MethodName = Annotated[str, Field(min_length=1, max_length=32)]


class ToleranceIn(In):
    """Relative tolerances on Ks and Ts (0.1: ±10 %), absolute on θ in seconds (null: not asked)."""

    K: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = 0.1
    tau: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = 0.1
    theta: Annotated[float | None, Field(gt=0, le=3600, allow_inf_nan=False)] = None


class AssignmentIn(In):
    """An assignment as a teacher writes it."""

    title: Annotated[str, Field(min_length=1, max_length=200)]
    instructions: Annotated[str, Field(max_length=20_000)] = ""
    rig: Annotated[str, Field(min_length=1, max_length=64)]
    methods: Annotated[
        list[_MethodName],
        Field(min_length=1, max_length=len(METHOD_NAMES), description="registry method names"),
    ]
    settings: Annotated[
        dict[_MethodName, dict[Annotated[str, Field(max_length=32)], Any]],
        Field(
            default_factory=dict,
            description="per method, the settings given (checked by the method registry)",
        ),
    ]
    deadline: Annotated[AwareDatetime, Field(strict=False)]
    tolerance: ToleranceIn = ToleranceIn()

    def draft(self) -> AssignmentDraft:
        """The service's draft."""
        return AssignmentDraft(
            title=self.title,
            instructions=self.instructions,
            rig=self.rig,
            methods=tuple(self.methods),
            deadline=self.deadline,
            tolerances=Tolerances(self.tolerance.K, self.tolerance.tau, self.tolerance.theta),
            settings=self.settings,
        )


class HandInIn(In):
    """A hand-in: one of the student's runs and their answers."""

    run_id: Annotated[int, Field(ge=1, le=MAX_ROW_ID)]
    K: _Finite
    tau: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    theta: Annotated[float | None, Field(ge=0, allow_inf_nan=False)] = None
    conclusion: Annotated[str, Field(max_length=4000)] = ""


class SubmissionOut(Out):
    """A hand-in and its automatic assessment (``assessment``: the checks, notes, mark)."""

    id: int
    assignment_id: int
    student: str
    display_name: str | None
    run_id: int | None
    answers: dict[str, Any]
    submitted_at: datetime
    late: bool
    current: bool
    state: str
    mark: float | None
    max: float
    assessment: dict[str, Any]
    marked_at: datetime
    handed_in_by: str | None = Field(None, description="the lab group member who handed it in")

    @classmethod
    def of(cls, s: SubmissionInfo) -> SubmissionOut:
        """Build from a :class:`~thermolab.lab.assignments.SubmissionInfo`."""
        return cls(
            id=s.id,
            assignment_id=s.assignment_id,
            student=s.student,
            display_name=s.display_name,
            run_id=s.run_id,
            answers=s.answers,
            submitted_at=s.submitted_at,
            late=s.late,
            current=s.current,
            state=s.state,
            mark=s.mark,
            max=s.max,
            assessment=s.assessment,
            marked_at=s.marked_at,
            handed_in_by=s.handed_in_by,
        )


class MyOverrideOut(Out):
    """A teacher's mark for the caller, and their comment (the final mark)."""

    mark: float
    max: float
    comment: str
    set_by: str
    set_at: datetime


class MyGroupOut(Out):
    """The caller's lab group: its name and its members' login names."""

    name: str
    members: list[str]


class AssignmentOut(Out):
    """An assignment; ``mine`` is the caller's own hand-ins, newest first."""

    id: int
    course: str
    course_title: str
    title: str
    instructions: str
    rig: str
    methods: list[str]
    settings: dict[str, Any]
    tolerance: dict[str, float | None]
    deadline: datetime
    created_by: str
    created_at: datetime
    updated_at: datetime
    mine: list[SubmissionOut]
    draft: bool = Field(False, description="copied from last term, not yet published")
    extended_deadline: datetime | None = Field(None, description="the caller's own deadline")
    override: MyOverrideOut | None = Field(None, description="a teacher's mark for the caller")
    group: MyGroupOut | None = Field(None, description="the caller's lab group")

    @classmethod
    def of(cls, a: AssignmentInfo) -> AssignmentOut:
        """Build from an :class:`~thermolab.lab.assignments.AssignmentInfo`."""
        return cls(
            id=a.id,
            course=a.course,
            course_title=a.course_title,
            title=a.title,
            instructions=a.instructions,
            rig=a.rig,
            methods=list(a.methods),
            settings=a.settings,
            tolerance=a.tolerances.to_dict(),
            deadline=a.deadline,
            created_by=a.created_by,
            created_at=a.created_at,
            updated_at=a.updated_at,
            mine=[SubmissionOut.of(s) for s in a.mine],
            draft=a.draft,
            extended_deadline=a.extended_deadline,
            override=None
            if a.override is None
            else MyOverrideOut(
                mark=a.override.mark,
                max=a.override.max,
                comment=a.override.comment,
                set_by=a.override.set_by,
                set_at=a.override.set_at,
            ),
            group=None
            if a.group is None
            else MyGroupOut(name=a.group.name, members=[u for u, _ in a.group.members]),
        )


@router.get(
    "/assignments",
    response_model=list[AssignmentOut],
    tags=["assignments"],
    summary="The assignments of my courses",
)
def list_assignments(who: UserDep, lab: LabDep) -> list[AssignmentOut]:
    """The assignments of every course the caller is in, by deadline (with their own hand-ins)."""
    return [AssignmentOut.of(a) for a in lab.assignments.for_user(who)]


@router.post(
    "/courses/{course}/assignments",
    response_model=AssignmentOut,
    status_code=status.HTTP_201_CREATED,
    tags=["assignments"],
    summary="Set an assignment",
    responses=documented_errors(403, 404, 422),
)
def create_assignment(
    course: CourseName, body: AssignmentIn, who: UserDep, lab: LabDep, request: Request
) -> AssignmentOut:
    """Set an experiment for a course: rig, methods and settings, deadline, tolerances.

    Teachers of the course only; methods and settings are checked by the
    method registry (422 ``invalid_parameter`` names what is allowed).
    """
    made = AssignmentOut.of(lab.assignments.create(course, who, body.draft()))
    audit(lab, who, request, AuditAction.ASSIGNMENT_CHANGED, f"{course} #{made.id}")
    return made


@router.get(
    "/assignments/{assignment_id}",
    response_model=AssignmentOut,
    tags=["assignments"],
    summary="An assignment",
    responses=documented_errors(403, 404, 422),
)
def get_assignment(assignment_id: AssignmentId, who: UserDep, lab: LabDep) -> AssignmentOut:
    """An assignment, for a member of its course, with the caller's own hand-ins."""
    return AssignmentOut.of(lab.assignments.get(assignment_id, who))


@router.put(
    "/assignments/{assignment_id}",
    response_model=AssignmentOut,
    tags=["assignments"],
    summary="Change an assignment",
    responses=documented_errors(403, 404, 422),
)
def update_assignment(
    assignment_id: AssignmentId, body: AssignmentIn, who: UserDep, lab: LabDep, request: Request
) -> AssignmentOut:
    """Change an assignment (teachers of its course); hand-ins keep the marks they got."""
    changed = AssignmentOut.of(lab.assignments.update(assignment_id, who, body.draft()))
    audit(lab, who, request, AuditAction.ASSIGNMENT_CHANGED, f"{changed.course} #{assignment_id}")
    return changed


@router.post(
    "/assignments/{assignment_id}/submissions",
    response_model=SubmissionOut,
    status_code=status.HTTP_201_CREATED,
    tags=["assignments"],
    summary="Hand in a run and answers",
    responses=documented_errors(403, 404, 409, 422),
)
async def hand_in(
    assignment_id: AssignmentId, body: HandInIn, who: UserDep, lab: LabDep
) -> SubmissionOut:
    """Hand in one of your finished runs on the assignment's rig with your Ks, Ts, θ.

    The run is identified again and the answers marked at once (the
    feedback is in ``assessment``); after the deadline the hand-in is kept
    and marked late. 409 ``conflict``: a run on another rig, not finished, or
    too short.
    """
    answers = Answers(body.K, body.tau, body.theta, body.conclusion)
    made = await anyio.to_thread.run_sync(
        lab.assignments.hand_in, assignment_id, who, body.run_id, answers
    )
    return SubmissionOut.of(made)


@router.get(
    "/assignments/{assignment_id}/submissions",
    response_model=list[SubmissionOut],
    tags=["assignments"],
    summary="The hand-ins of an assignment",
    responses=documented_errors(403, 404, 422),
)
def list_submissions(assignment_id: AssignmentId, who: UserDep, lab: LabDep) -> list[SubmissionOut]:
    """Every hand-in (current ones first), for the teachers of the course."""
    return [SubmissionOut.of(s) for s in lab.assignments.submissions(assignment_id, who)]


@router.get(
    "/courses/{course}/grades.csv",
    tags=["assignments"],
    summary="Grades as CSV",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}, **documented_errors(403, 404, 422)},
)
def grades(course: CourseName, who: UserDep, lab: LabDep, sheet: SheetDep) -> Response:
    """One row per student × assignment of the course (teachers of the course only).

    ``?dialect=pt-BR`` (or ``en``, ``es``) and ``tz``: the spreadsheet form
    (:mod:`thermolab.lab.spreadsheets`); without them the machine form.
    """
    rows = lab.assignments.grade_rows(course, who)
    return Response(
        grades_csv(rows, sheet),
        media_type="text/csv" if sheet is None else "text/csv; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="grades-{course}.csv"'},
    )
