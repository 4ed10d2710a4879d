"""One student's later deadline for an assignment.

The course's deadline is every student's; an extension gives one student a
later one. A hand-in is late when it comes after the student's own deadline
(the extension's, else the assignment's); nothing else about late hand-ins
changes (they are kept and marked, flagged late). Granting or removing an
extension flags the student's hand-ins again against their new deadline, so
an extension given after the fact (a student was ill) clears the flag.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from thermolab.errors import InvalidParameterError
from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.users import Principal
from thermolab.lab.assignments.rows import assignment_with_course, course_student
from thermolab.lab.classes.authorize import require_in_course
from thermolab.lab.classes.closed import require_open
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.assignment_models import Assignment, Submission
from thermolab.lab.db.grading_models import DeadlineExtension

__all__ = ["ExtensionInfo", "ExtensionService", "extensions_of", "own_deadline"]


@dataclass(frozen=True, slots=True)
class ExtensionInfo:
    """A student's own deadline for an assignment."""

    assignment_id: int
    course: str
    student: str
    deadline: datetime
    set_by: str
    set_at: datetime


class ExtensionService:
    """Extend an assignment's deadline for one student, or take the extension back.

    Parameters
    ----------
    db : Database
    clock : LabClock
    """

    def __init__(self, db: Database, clock: LabClock) -> None:
        self._db = db
        self._clock = clock

    def set(
        self, assignment_id: int, who: Principal, student: str, deadline: datetime
    ) -> ExtensionInfo:
        """Let ``student`` hand in until ``deadline`` (after the assignment's) without being late.

        Raises
        ------
        AccessDeniedError
            Not a teacher of the course.
        NotFoundError
            No such assignment, or no such student in its course.
        InvalidParameterError
            A deadline without its time zone, or not after the assignment's.
        ConflictError
            The course is closed.
        """
        if deadline.tzinfo is None:
            raise InvalidParameterError("the new deadline must carry its time zone")
        now = self._clock.now()
        with self._db.write() as session:
            row, course = assignment_with_course(session, assignment_id)
            require_in_course(session, course, who, Action.COURSE_EXTENSIONS)
            require_open(course, "extend deadlines")
            if deadline <= row.deadline:
                raise InvalidParameterError(
                    f"the new deadline must come after the assignment's, "
                    f"{row.deadline.isoformat(timespec='minutes')}"
                )
            person = course_student(session, course, student)
            found = extensions_of(session, [row.id]).get((row.id, person.id))
            if found is None:
                found = DeadlineExtension(assignment_id=row.id, user_id=person.id)
                session.add(found)
            found.deadline, found.set_by, found.set_at = deadline, who.username, now
            _flag_late(session, row.id, person.id, deadline)
            session.flush()
            return ExtensionInfo(row.id, course.name, person.username, deadline, who.username, now)

    def remove(self, assignment_id: int, who: Principal, student: str) -> str:
        """Take the extension back: the assignment's deadline is the student's again.

        Returns the course's name.
        """
        with self._db.write() as session:
            row, course = assignment_with_course(session, assignment_id)
            require_in_course(session, course, who, Action.COURSE_EXTENSIONS)
            require_open(course, "extend deadlines")
            person = course_student(session, course, student)
            session.execute(
                delete(DeadlineExtension).where(
                    DeadlineExtension.assignment_id == row.id,
                    DeadlineExtension.user_id == person.id,
                )
            )
            _flag_late(session, row.id, person.id, row.deadline)
            return course.name


def extensions_of(
    session: Session, assignment_ids: Iterable[int]
) -> dict[tuple[int, int], DeadlineExtension]:
    """The extensions of the assignments, by ``(assignment_id, user_id)``."""
    return {
        (e.assignment_id, e.user_id): e
        for e in session.scalars(
            select(DeadlineExtension).where(
                DeadlineExtension.assignment_id.in_(list(assignment_ids))
            )
        )
    }


def own_deadline(assignment: Assignment, extension: DeadlineExtension | None) -> datetime:
    """The student's deadline: the later of the assignment's and their extension's.

    An assignment's deadline moved past an extension given earlier wins: an
    extension never makes a student's deadline sooner.
    """
    if extension is None:
        return assignment.deadline
    return max(assignment.deadline, extension.deadline)


def _flag_late(session: Session, assignment_id: int, user_id: int, deadline: datetime) -> None:
    for s in session.scalars(
        select(Submission).where(
            Submission.assignment_id == assignment_id, Submission.user_id == user_id
        )
    ):
        s.late = s.submitted_at > deadline
