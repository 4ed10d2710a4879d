"""A course's teaching assistants: :class:`AssistantService`.

An assistant is a place in one course (``course_members.role =
assistant``), given by a teacher of the course to an existing account of
either kind; what the place allows is the policy table's
(:mod:`thermolab.lab.accounts.policy`). An LMS's ``TeachingAssistant``
launches into the same place (:mod:`thermolab.lab.lti.accounts`).

Someone already in the course as a student or teacher is not made an
assistant of it: a student assisting their own course would see their
classmates' marks, and a teacher would lose rights. Remove them first.
"""

from __future__ import annotations

from sqlalchemy import delete, select

from thermolab.errors import ConflictError, NotFoundError
from thermolab.lab.accounts.users import user_named
from thermolab.lab.classes.closed import require_open
from thermolab.lab.classes.course_access import course_named
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.models import CourseMember, MemberRole

__all__ = ["AssistantService"]


class AssistantService:
    """Add and remove a course's teaching assistants (the caller checked the policy).

    Parameters
    ----------
    db : Database
    clock : LabClock
    """

    def __init__(self, db: Database, clock: LabClock) -> None:
        self._db = db
        self._clock = clock

    def add(self, course: str, username: str) -> str:
        """Make ``username`` an assistant of ``course``; return their login name.

        Adding an assistant twice changes nothing.

        Raises
        ------
        NotFoundError
            An unknown course or person.
        ConflictError
            The person is a student or teacher of the course.
        CourseClosedError
            The course is closed.
        """
        with self._db.write() as session:
            found = course_named(session, course)
            require_open(found, "add teaching assistants")
            user = user_named(session, username)
            held = session.scalar(
                select(CourseMember).where(
                    CourseMember.course_id == found.id, CourseMember.user_id == user.id
                )
            )
            if held is None:
                session.add(
                    CourseMember(
                        course_id=found.id,
                        user_id=user.id,
                        role=MemberRole.ASSISTANT.value,
                        joined_at=self._clock.now(),
                    )
                )
            elif held.role != MemberRole.ASSISTANT.value:
                raise ConflictError(
                    f"{user.username} is a {held.role} of course {found.name!r}; "
                    "remove them from it before making them an assistant",
                    case="member_has_other_role",
                )
            return user.username

    def remove(self, course: str, username: str) -> str:
        """Take ``username``'s assistant place in ``course``; return their login name.

        Raises
        ------
        NotFoundError
            An unknown course, or a person who does not assist it.
        CourseClosedError
            The course is closed.
        """
        with self._db.write() as session:
            found = course_named(session, course)
            require_open(found, "remove teaching assistants")
            user = user_named(session, username)
            gone = session.execute(
                delete(CourseMember).where(
                    CourseMember.course_id == found.id,
                    CourseMember.user_id == user.id,
                    CourseMember.role == MemberRole.ASSISTANT.value,
                )
            )
            if not getattr(gone, "rowcount", 0):
                raise NotFoundError(f"{user.username} does not assist course {found.name!r}")
            return user.username
