"""A course found by its name, and who in it may act: every class module's way into a course."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import AccessDeniedError, NotFoundError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.models import Course, CourseMember, Role

__all__ = ["course_named", "require_member"]


def course_named(session: Session, name: str, *, lock: bool = False) -> Course:
    """The course called ``name`` (lower case; ``NotFoundError`` if none); ``lock``: its row
    held to the transaction's end (``FOR UPDATE``), so no close slips in after a check."""
    query = select(Course).where(Course.name == name.strip().lower())
    course = session.scalars(query.with_for_update() if lock else query)
    found = course.one_or_none()
    if found is None:
        raise NotFoundError(f"no course called {name!r}")
    return found


def require_member(
    session: Session, course: Course, who: Principal, role: Role | None, action: str
) -> None:
    """Refuse ``action`` unless ``who`` is in ``course`` (as ``role``, if given).

    Raises
    ------
    AccessDeniedError
        Naming the course, and for a teacher's action who can let them in.

    A lab administrator reaches every course (:mod:`thermolab.lab.accounts.policy`)
    for everything but a student's own acts (handing in).
    """
    if who.is_admin and role is not Role.STUDENT:
        return
    held = session.scalar(
        select(CourseMember.role).where(
            CourseMember.course_id == course.id, CourseMember.user_id == who.user_id
        )
    )
    if held is None or (role is not None and held != role.value):
        what = "a member" if role is None else f"a {role.value}"
        hint = "; ask one of them to add you as a teacher" if role is Role.TEACHER else ""
        raise AccessDeniedError(f"only {what} of course {course.name!r} may {action}{hint}")
