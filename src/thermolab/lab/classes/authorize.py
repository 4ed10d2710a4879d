"""The policy table (:mod:`thermolab.lab.accounts.policy`) checked against the courses.

:class:`Authorizer` answers "may this person do this to that course, or to
that person?" with one query: a teacher's ``taught`` scope is the courses
where they are a ``teacher`` member, and a person in it is a student of one
of those courses (never another teacher, whose password is an
administrator's business).
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import AccessDeniedError, NotFoundError
from thermolab.lab.accounts.policy import POLICY, Action, Scope, require_lab, scope_of
from thermolab.lab.accounts.security import normalize_username
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db import Database
from thermolab.lab.db.models import Course, CourseMember, Role, User

__all__ = ["Authorizer"]


class Authorizer:
    """Check an action of the policy table on a course or a person.

    Parameters
    ----------
    db : Database
    """

    def __init__(self, db: Database) -> None:
        self._db = db

    def require(self, who: Principal, action: Action) -> None:
        """Refuse ``action`` unless ``who`` may do it at all (in some scope).

        Raises
        ------
        AccessDeniedError
            When the table gives ``who`` no scope for ``action``.
        """
        if scope_of(who, action) is Scope.NONE:
            whom = [a.value for a, scope in POLICY[action].items() if scope is not Scope.NONE]
            names = " or ".join("a lab administrator" if w == "admin" else f"a {w}" for w in whom)
            raise AccessDeniedError(f"only {names} may {action}")

    def require_lab(self, who: Principal, action: Action) -> None:
        """Refuse ``action`` unless ``who`` may do it lab-wide (an administrator's)."""
        require_lab(who, action)

    def require_course(self, who: Principal, action: Action, course: str) -> None:
        """Refuse ``action`` on ``course`` unless ``who`` reaches it.

        Raises
        ------
        AccessDeniedError
            Naming the course, for a teacher who does not teach it.
        NotFoundError
            For an unknown course, to someone who could act on it if it existed.
        """
        scope = scope_of(who, action)
        if scope is Scope.LAB:
            return
        if scope is not Scope.TAUGHT:
            require_lab(who, action)
        with self._db.read() as session:
            found = session.scalar(select(Course.id).where(Course.name == course.strip().lower()))
            if found is None:
                raise NotFoundError(f"no course called {course!r}")
            if not _teaches(session, who.user_id, found):
                raise AccessDeniedError(
                    f"only a teacher of course {course!r} (or a lab administrator) may {action}"
                )

    def taught(self, who: Principal, action: Action) -> frozenset[str] | None:
        """Return the names of the courses ``who`` may ``action`` (``None``: every course)."""
        scope = scope_of(who, action)
        if scope is Scope.LAB:
            return None
        if scope is not Scope.TAUGHT:
            return frozenset()
        with self._db.read() as session:
            return frozenset(
                session.scalars(
                    select(Course.name)
                    .join(CourseMember, CourseMember.course_id == Course.id)
                    .where(
                        CourseMember.user_id == who.user_id,
                        CourseMember.role == Role.TEACHER.value,
                    )
                )
            )

    def require_person(self, who: Principal, action: Action, username: str) -> None:
        """Refuse ``action`` on the account ``username`` unless ``who`` reaches it.

        A teacher reaches the students of the courses they teach; ``self``
        reaches one's own account; an administrator everyone.

        Raises
        ------
        AccessDeniedError
            Otherwise (also for an unknown name, so that names cannot be probed).
        """
        scope = scope_of(who, action)
        if scope is Scope.LAB:
            return
        try:
            name = normalize_username(username)
        except ValueError:
            name = username
        if scope is Scope.SELF and name == who.username:
            return
        if scope is Scope.TAUGHT:
            with self._db.read() as session:
                target = session.scalars(select(User).where(User.username == name)).one_or_none()
                if target is not None and target.role == Role.STUDENT.value:
                    theirs = select(CourseMember.course_id).where(CourseMember.user_id == target.id)
                    shared = session.scalar(
                        select(CourseMember.id).where(
                            CourseMember.user_id == who.user_id,
                            CourseMember.role == Role.TEACHER.value,
                            CourseMember.course_id.in_(theirs),
                        )
                    )
                    if shared is not None:
                        return
            raise AccessDeniedError(
                f"only a lab administrator, or a teacher of {username!r}'s course, may {action}"
            )
        require_lab(who, action)


def _teaches(session: Session, user_id: int, course_id: int) -> bool:
    held = session.scalar(
        select(CourseMember.role).where(
            CourseMember.course_id == course_id, CourseMember.user_id == user_id
        )
    )
    return held == Role.TEACHER.value
