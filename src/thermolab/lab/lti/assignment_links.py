"""Assignments in the LMS: linked by deep linking, their marks posted to its gradebook.

* **Deep linking.** A teacher who launched the picker from an LMS course
  sees the assignments of the lab course that LMS course fills (target
  ``assignment:<id>``); the link's launch opens the assignment's page
  (:func:`~thermolab.lab.lti.deep_linking.target_path`), signed in, in the
  course.
* **Grades.** Each hand-in the lab marks (``on_marked``, after its commit)
  queues the mark in the grade outbox for the LMS activities of the same
  platform that link ``assignment:<id>`` and for which the student has an LMS
  identity; a re-hand-in queues the new mark, which wins (AGS keeps the
  latest). A hand-in left for ``review`` (no trustworthy identification, no
  mark) posts nothing: the LMS keeps showing the last mark until the teacher
  has one. Delivery is the outbox's (retried, visible to the teacher).
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from sqlalchemy import select

from thermolab.lab.assignments import AssignmentService, GradeRow
from thermolab.lab.db import Database
from thermolab.lab.db.assignment_models import Assignment
from thermolab.lab.db.models import Course, User
from thermolab.lab.lti.deep_linking import LinkableItems, LinkItem

__all__ = ["assignment_target", "follow_assignments"]

log = logging.getLogger(__name__)

QueueForUser = Callable[..., list[int]]


def assignment_target(assignment_id: int) -> str:
    """The deep-link target of an assignment.

    Examples
    --------
    >>> assignment_target(7)
    'assignment:7'
    """
    return f"assignment:{assignment_id}"


def follow_assignments(
    db: Database,
    assignments: AssignmentService,
    linkable: LinkableItems,
    queue_for_user: QueueForUser,
    kick: Callable[[], None],
) -> Callable[[], None]:
    """Offer a course's assignments to deep linking and post their marks; return an unsubscribe.

    ``queue_for_user`` is :meth:`~thermolab.lab.lti.LtiService.queue_grade_for_user`,
    ``kick`` wakes the outbox's delivery.
    """

    def course_items(course: str) -> list[LinkItem]:
        with db.read() as session:
            rows = session.execute(
                select(Assignment.id, Assignment.title, Assignment.rig_id)
                .join(Course, Course.id == Assignment.course_id)
                .where(Course.name == course)
                .order_by(Assignment.id)
            ).all()
        return [LinkItem("assignment", assignment_target(i), title, rig) for i, title, rig in rows]

    def marked(row: GradeRow) -> None:
        if row.state != "marked" or row.mark is None:
            return  # review: no mark to post (see the module's notes)
        with db.read() as session:
            user_id = session.scalar(select(User.id).where(User.username == row.student))
        if user_id is None:
            return
        queued = queue_for_user(
            user_id=user_id,
            target=assignment_target(row.assignment_id),
            score_given=row.mark,
            score_maximum=row.max,
            timestamp=row.marked_at,
        )
        if queued:
            log.info(
                "assignment %d: %s's mark queued for the LMS (%d rows)",
                row.assignment_id,
                row.student,
                len(queued),
            )
            kick()

    linkable.register_course(course_items)
    return assignments.on_marked(marked)
