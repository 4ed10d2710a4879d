"""A teacher's mark for one student, with a comment; the automatic mark stays beside it.

An override belongs to a student and an assignment, not to one hand-in: it
stands over a later hand-in too (the teacher's judgement holds until they
remove it), while the page and the grades show the newest hand-in's
automatic mark beside it. Only a student who handed something in has a mark
to override (nothing handed in stays "not handed in"). Each change tells the
"submission marked" listeners (:meth:`.service.AssignmentService.on_marked`)
the student's new grade, so the LMS gets the final mark.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from thermolab.errors import ConflictError, InvalidParameterError
from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.users import Principal
from thermolab.lab.assignments.grades import GradeRow
from thermolab.lab.assignments.marking import MARK_MAX
from thermolab.lab.assignments.rows import (
    OverrideInfo,
    assignment_with_course,
    course_student,
    grade_row,
    override_info,
)
from thermolab.lab.classes.authorize import require_in_course
from thermolab.lab.classes.closed import require_open
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.assignment_models import Submission
from thermolab.lab.db.grading_models import GradeOverride

__all__ = ["MAX_COMMENT", "OverrideService", "overrides_of"]

#: The longest comment on an overridden mark.
MAX_COMMENT = 2_000


class OverrideService:
    """Override a student's mark with a comment, or remove the override.

    Parameters
    ----------
    db : Database
    clock : LabClock
    tell : callable
        Called with the student's new :class:`~.grades.GradeRow` after each change.
    """

    def __init__(self, db: Database, clock: LabClock, tell: Callable[[GradeRow], None]) -> None:
        self._db = db
        self._clock = clock
        self._tell = tell

    def set(
        self, assignment_id: int, who: Principal, student: str, mark: float, comment: str
    ) -> tuple[OverrideInfo, GradeRow]:
        """Give ``student`` ``mark`` (0 to the maximum) on the assignment, saying why.

        Raises
        ------
        AccessDeniedError
            Not a teacher of the course.
        NotFoundError
            No such assignment, or no such student in its course.
        ConflictError
            The student handed nothing in, or the course is closed.
        InvalidParameterError
            A mark out of range, or no comment.
        """
        if not (math.isfinite(mark) and 0 <= mark <= MARK_MAX):
            raise InvalidParameterError(f"the mark must be from 0 to {MARK_MAX:g}")
        words = comment.strip()
        if not 0 < len(words) <= MAX_COMMENT:
            raise InvalidParameterError(
                f"say why in a comment of 1 to {MAX_COMMENT} characters: the student reads it"
            )
        now = self._clock.now()
        with self._db.write() as session:
            row, course = assignment_with_course(session, assignment_id)
            require_in_course(session, course, who, Action.COURSE_MARK_OVERRIDE)
            require_open(course, "override marks")
            person = course_student(session, course, student)
            current = _current(session, row.id, person.id)
            if current is None:
                raise ConflictError(
                    f"{person.username} has handed nothing in for this assignment: "
                    "there is no mark to override",
                    case="nothing_handed_in",
                )
            found = overrides_of(session, [row.id]).get((row.id, person.id))
            if found is None:
                found = GradeOverride(assignment_id=row.id, user_id=person.id)
                session.add(found)
            found.mark, found.comment, found.set_by, found.set_at = mark, words, who.username, now
            session.flush()
            grade = grade_row(course, row, person.username, person.display_name, current, found)
            made = override_info(found, person.username)
        self._tell(grade)
        return made, grade

    def remove(self, assignment_id: int, who: Principal, student: str) -> GradeRow:
        """Take the override away: the automatic mark is the final one again."""
        with self._db.write() as session:
            row, course = assignment_with_course(session, assignment_id)
            require_in_course(session, course, who, Action.COURSE_MARK_OVERRIDE)
            require_open(course, "override marks")
            person = course_student(session, course, student)
            session.execute(
                delete(GradeOverride).where(
                    GradeOverride.assignment_id == row.id, GradeOverride.user_id == person.id
                )
            )
            current = _current(session, row.id, person.id)
            grade = grade_row(course, row, person.username, person.display_name, current)
        self._tell(grade)
        return grade


def overrides_of(
    session: Session, assignment_ids: Iterable[int]
) -> dict[tuple[int, int], GradeOverride]:
    """The overrides of the assignments, by ``(assignment_id, user_id)``."""
    return {
        (o.assignment_id, o.user_id): o
        for o in session.scalars(
            select(GradeOverride).where(GradeOverride.assignment_id.in_(list(assignment_ids)))
        )
    }


def _current(session: Session, assignment_id: int, user_id: int) -> Submission | None:
    return session.scalars(
        select(Submission).where(
            Submission.assignment_id == assignment_id,
            Submission.user_id == user_id,
            Submission.current,
        )
    ).one_or_none()
