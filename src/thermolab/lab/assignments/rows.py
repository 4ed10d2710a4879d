"""What the assignment services answer, built from the database's rows.

The information objects (:class:`AssignmentInfo`, :class:`SubmissionInfo`,
:class:`OverrideInfo`, :class:`GroupInfo`) and the lookups every assignment
module shares (an assignment with its course, a student of a course), so that
:mod:`.service`, :mod:`.overrides`, :mod:`.extensions` and :mod:`.groups`
build them the same way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import NotFoundError
from thermolab.lab.assignments.grades import GradeRow
from thermolab.lab.assignments.marking import MARK_MAX, Tolerances
from thermolab.lab.db.assignment_models import Assignment, Submission
from thermolab.lab.db.grading_models import GradeOverride
from thermolab.lab.db.models import Course, CourseMember, Role, User

__all__ = [
    "AssignmentInfo",
    "GroupInfo",
    "OverrideInfo",
    "SubmissionInfo",
    "assignment_with_course",
    "course_named",
    "course_student",
    "grade_row",
    "override_info",
    "submission_info",
    "tolerances_of",
]


@dataclass(frozen=True, slots=True)
class SubmissionInfo:
    """A hand-in and its assessment (``handed_in_by``: the group member who handed it in)."""

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
    handed_in_by: str | None = None


@dataclass(frozen=True, slots=True)
class OverrideInfo:
    """A teacher's mark for a student, and the comment the student reads."""

    student: str
    mark: float
    max: float
    comment: str
    set_by: str
    set_at: datetime


@dataclass(frozen=True, slots=True)
class GroupInfo:
    """A lab group of a course: its members (login name, display name) by login name."""

    id: int
    course: str
    name: str
    members: tuple[tuple[str, str | None], ...]
    created_by: str
    created_at: datetime


@dataclass(frozen=True, slots=True)
class AssignmentInfo:
    """An assignment; for a student, their hand-ins (newest first) and their own terms.

    ``extended_deadline``, ``override`` and ``group`` are the caller's: their
    later deadline, a teacher's mark for them, the lab group they hand in with.
    """

    id: int
    course: str
    course_title: str
    title: str
    instructions: str
    rig: str
    methods: tuple[str, ...]
    settings: dict[str, Any]
    tolerances: Tolerances
    deadline: datetime
    created_by: str
    created_at: datetime
    updated_at: datetime
    mine: tuple[SubmissionInfo, ...] = ()
    #: Copied from last term's course and not yet published: its teachers' only.
    draft: bool = False
    extended_deadline: datetime | None = None
    override: OverrideInfo | None = None
    group: GroupInfo | None = None


def tolerances_of(row: Assignment) -> Tolerances:
    """The assignment's tolerances."""
    return Tolerances(K=row.tol_k, tau=row.tol_tau, theta=row.tol_theta)


def course_named(session: Session, name: str) -> Course:
    """The course called ``name`` (``NotFoundError`` if there is none)."""
    found = session.scalars(select(Course).where(Course.name == name.strip().lower())).one_or_none()
    if found is None:
        raise NotFoundError(f"no course called {name!r}")
    return found


def assignment_with_course(session: Session, assignment_id: int) -> tuple[Assignment, Course]:
    """The assignment and its course (``NotFoundError`` if there is none)."""
    found = session.execute(
        select(Assignment, Course)
        .join(Course, Course.id == Assignment.course_id)
        .where(Assignment.id == assignment_id)
    ).one_or_none()
    if found is None:
        raise NotFoundError(f"no assignment {assignment_id}")
    return found[0], found[1]


def course_student(session: Session, course: Course, username: str) -> User:
    """The student ``username`` of ``course`` (``NotFoundError`` for anyone else)."""
    found = session.scalars(
        select(User)
        .join(CourseMember, CourseMember.user_id == User.id)
        .where(
            User.username == username.strip().lower(),
            CourseMember.course_id == course.id,
            CourseMember.role == Role.STUDENT.value,
        )
    ).one_or_none()
    if found is None:
        raise NotFoundError(f"no student called {username!r} in course {course.name!r}")
    return found


def info(
    row: Assignment,
    course: Course,
    mine: Sequence[SubmissionInfo] = (),
    **theirs: Any,
) -> AssignmentInfo:
    """An :class:`AssignmentInfo` (``theirs``: the caller's extension, override, group)."""
    return AssignmentInfo(
        id=row.id,
        course=course.name,
        course_title=course.title,
        title=row.title,
        instructions=row.instructions,
        rig=row.rig_id,
        methods=tuple(row.methods),
        settings=dict(row.settings),
        tolerances=tolerances_of(row),
        deadline=row.deadline,
        created_by=row.created_by,
        created_at=row.created_at,
        updated_at=row.updated_at,
        mine=tuple(mine),
        draft=bool(row.draft),
        **theirs,
    )


def submission_info(s: Submission, display: str | None) -> SubmissionInfo:
    """A :class:`SubmissionInfo` of a stored hand-in."""
    return SubmissionInfo(
        id=s.id,
        assignment_id=s.assignment_id,
        student=s.username,
        display_name=display,
        run_id=s.run_id,
        answers=dict(s.answers),
        submitted_at=s.submitted_at,
        late=bool(s.late),
        current=bool(s.current),
        state=s.state,
        mark=s.mark,
        max=s.max_mark,
        assessment=dict(s.assessment),
        marked_at=s.marked_at,
        handed_in_by=s.handed_in_by,
    )


def override_info(o: GradeOverride, student: str) -> OverrideInfo:
    """An :class:`OverrideInfo` of a stored override."""
    return OverrideInfo(student, o.mark, MARK_MAX, o.comment, o.set_by, o.set_at)


def grade_row(
    course: Course,
    a: Assignment,
    username: str,
    display: str | None,
    s: Submission | None,
    override: GradeOverride | None = None,
) -> GradeRow:
    """The student's standing: the final mark (a teacher's override, else the automatic one).

    An overridden hand-in is ``marked`` whatever its automatic state (a
    teacher gave it a mark); ``automatic_mark`` keeps the lab's.
    """
    if s is None:
        return GradeRow(
            course.name, a.id, a.title, username, display, "missing", None, MARK_MAX,
            None, None, False, None,
        )  # fmt: skip
    answers = s.answers
    state, mark, marked_at, comment = s.state, s.mark, s.marked_at, ""
    if override is not None:
        state, mark, marked_at, comment = "marked", override.mark, override.set_at, override.comment
    return GradeRow(
        course.name, a.id, a.title, username, display, state, mark, s.max_mark,
        marked_at, s.submitted_at, bool(s.late), s.run_id,
        answers.get("K"), answers.get("tau"), answers.get("theta"),
        str(answers.get("conclusion") or ""), s.mark, comment,
    )  # fmt: skip
