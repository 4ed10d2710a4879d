"""Where each student's assignment state comes from: the extension point of the analytics.

Assignments (issue #10 item 4) live in tables of their own. The analytics do
not read them directly: :class:`~thermolab.lab.analytics.service.AnalyticsService`
takes an :data:`AssignmentSource`, a function that answers, in the analytics'
read transaction, one :class:`AssignmentSummary` per student of a course.
:func:`assignment_state` is the lab's source (``Lab.__init__`` passes it): two
grouped queries over the assignment tables (:mod:`thermolab.lab.db.assignment_models`),
whatever the size of the class. :func:`no_assignments` answers nothing.
A student the source leaves out shows "no assignment data" (``null`` in the
API, empty CSV cells): with :func:`assignment_state`, every student of a
course that set no assignment open in the window.

Which assignments count: those *open during the window*, set before its end
and due at or after its start (an assignment still open now counts in the
default window, which ends now). Their state is today's: each student's
``current`` hand-in (the newest), whenever it was handed in, with its final
mark: a teacher's override (:mod:`thermolab.lab.assignments.overrides`) where
there is one, else the automatic mark.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import Float, and_, case, cast, func, select
from sqlalchemy.orm import Session

from thermolab.lab.analytics.sql import at
from thermolab.lab.db.assignment_models import Assignment, Submission
from thermolab.lab.db.grading_models import GradeOverride

__all__ = ["AssignmentSource", "AssignmentSummary", "assignment_state", "no_assignments"]


@dataclass(frozen=True, slots=True)
class AssignmentSummary:
    """One student's assignments in a course, within the analytics' window.

    Attributes
    ----------
    assigned : int
        Assignments set for the course (open during the window).
    submitted : int
        Of those, handed in (late ones included).
    late : int
        Handed in after the deadline.
    marked : int
        Marked (by the lab, or by a teacher's override).
    mean_mark : float or None
        Mean of the final marks (a teacher's override, else the lab's) as
        percentages of their maximum, 0-100 (``None``: nothing marked).
    """

    assigned: int
    submitted: int
    late: int
    marked: int
    mean_mark: float | None


#: ``(session, course_id, student_ids, window_from, window_to) -> {user_id: summary}``.
AssignmentSource = Callable[
    [Session, int, Sequence[int], datetime, datetime], Mapping[int, AssignmentSummary]
]


def no_assignments(
    session: Session,
    course_id: int,
    student_ids: Sequence[int],
    window_from: datetime,
    window_to: datetime,
) -> Mapping[int, AssignmentSummary]:
    """The source while the lab has no assignments: nobody has any data."""
    return {}


def assignment_state(
    session: Session,
    course_id: int,
    student_ids: Sequence[int],
    window_from: datetime,
    window_to: datetime,
) -> Mapping[int, AssignmentSummary]:
    """Each student's current hand-ins to the course's assignments open in the window.

    Every student gets a summary when at least one assignment counts (zeros
    for one who handed nothing in); nobody does otherwise.
    """
    counted = select(Assignment.id).where(
        Assignment.course_id == course_id,
        Assignment.created_at < at("window_to", window_to),
        Assignment.deadline >= at("window_from", window_from),
    )
    assigned = session.scalar(select(func.count()).select_from(counted.subquery())) or 0
    if assigned == 0 or not student_ids:
        return {}
    final = func.coalesce(GradeOverride.mark, Submission.mark)
    percent = case(
        (
            and_(final.is_not(None), Submission.max_mark > 0),
            100.0 * cast(final, Float) / Submission.max_mark,
        ),
    )
    rows = session.execute(
        select(
            Submission.user_id,
            func.count(),
            func.count(case((Submission.late, 1))),
            func.count(percent),
            func.avg(percent),
        )
        .select_from(Submission)
        .outerjoin(
            GradeOverride,
            and_(
                GradeOverride.assignment_id == Submission.assignment_id,
                GradeOverride.user_id == Submission.user_id,
            ),
        )
        .where(
            Submission.current,
            Submission.assignment_id.in_(counted),
            Submission.user_id.in_(list(student_ids)),
        )
        .group_by(Submission.user_id)
    ).all()
    handed = {
        user_id: (int(n), int(late), int(marked), None if mean is None else float(mean))
        for user_id, n, late, marked, mean in rows
    }
    out = {}
    for user_id in student_ids:
        n, late, marked, mean = handed.get(user_id, (0, 0, 0, None))
        out[user_id] = AssignmentSummary(assigned, n, late, marked, mean)
    return out
