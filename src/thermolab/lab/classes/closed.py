"""The one check every change to a course passes: the course is not closed.

A course closed at the end of its term (:mod:`thermolab.lab.classes.term`)
is read and exported as before, and changed by nobody: no enrolment, no class
list, no hand-in, no booking, no assignment, no limits, no rigs, no new code.
Each service that changes a course calls :func:`require_open` inside its
write transaction, on the row it has just read. Bookings read it locked
(``FOR UPDATE`` on PostgreSQL; SQLite has one writer): a close cancels the
course's bookings to come, so one made as it closes waits for it and is refused.
"""

from __future__ import annotations

from thermolab.errors import CourseClosedError
from thermolab.lab.db.models import Course

__all__ = ["require_open"]


def require_open(course: Course, action: str) -> None:
    """Refuse ``action`` on a closed ``course``.

    Raises
    ------
    CourseClosedError
        Naming the course, when and by whom it was closed (a 409 ``course_closed``).
    """
    if course.closed_at is not None:
        when = course.closed_at.date().isoformat()
        raise CourseClosedError(
            f"course {course.name!r} was closed on {when} by {course.closed_by or 'someone'}; "
            f"it can be read but no one may {action} (an administrator can reopen it)"
        )
