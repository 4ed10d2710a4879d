"""Each student's standing on one assignment, as its teachers' page shows it.

One row per student of the course: the final mark (a teacher's override,
else the automatic one) with the automatic mark and the comment beside it,
the student's own deadline (an extension's, else the assignment's) and their
lab group. Read by the teachers and assistants of the course.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import select

from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.users import Principal
from thermolab.lab.assignments.extensions import extensions_of, own_deadline
from thermolab.lab.assignments.grades import GradeRow
from thermolab.lab.assignments.overrides import overrides_of
from thermolab.lab.assignments.rows import assignment_with_course, grade_row
from thermolab.lab.classes.authorize import require_in_course
from thermolab.lab.db import Database
from thermolab.lab.db.assignment_models import Submission
from thermolab.lab.db.grading_models import LabGroup, LabGroupMember
from thermolab.lab.db.models import CourseMember, Role, User

__all__ = ["Standing", "standings"]


@dataclass(frozen=True, slots=True)
class Standing:
    """A student's grade on the assignment, their deadline and their lab group."""

    grade: GradeRow
    deadline: datetime
    extended: bool
    group: str | None


def standings(db: Database, assignment_id: int, who: Principal) -> list[Standing]:
    """Every student of the assignment's course, by login name (teachers and assistants)."""
    with db.read() as session:
        row, course = assignment_with_course(session, assignment_id)
        require_in_course(session, course, who, Action.COURSE_HAND_INS)
        students = session.execute(
            select(User.id, User.username, User.display_name)
            .join(CourseMember, CourseMember.user_id == User.id)
            .where(CourseMember.course_id == course.id, CourseMember.role == Role.STUDENT.value)
            .order_by(User.username)
        ).all()
        current = {
            s.user_id: s
            for s in session.scalars(
                select(Submission).where(Submission.assignment_id == row.id, Submission.current)
            )
        }
        # A Result has keys(): dict() would read it as a mapping; its rows are the pairs.
        groups: dict[int, str] = dict(
            session.execute(
                select(LabGroupMember.user_id, LabGroup.name)
                .join(LabGroup, LabGroup.id == LabGroupMember.group_id)
                .where(LabGroupMember.course_id == course.id)
            ).all()
        )
        overridden = overrides_of(session, [row.id])
        extended = extensions_of(session, [row.id])
        out = []
        for user_id, username, display in students:
            s = current.get(user_id)
            o = overridden.get((row.id, user_id)) if s is not None else None
            e = extended.get((row.id, user_id))
            out.append(
                Standing(
                    grade_row(course, row, username, display, s, o),
                    own_deadline(row, e),
                    e is not None,
                    groups.get(user_id),
                )
            )
        return out
