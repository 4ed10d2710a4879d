"""Lab groups: students of a course who share a run and a hand-in.

A teacher forms a group of two or more students of a course (a student is in
at most one group of a course). Then any member may hand in a finished run
of any member, for everyone: the hand-in is stored once per member (each
member's current hand-in, marked the same), so the grades, the LMS and the
analytics see every member marked. Each member keeps their own deadline
(an extension is per student) and their own override. Removing a group
keeps the hand-ins its members made; from then on each hands in alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime

from sqlalchemy import delete, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from thermolab.errors import ConflictError, InvalidParameterError, NotFoundError
from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.users import Principal
from thermolab.lab.assignments.rows import GroupInfo, course_named, course_student
from thermolab.lab.classes.authorize import require_in_course
from thermolab.lab.classes.closed import require_open
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.grading_models import LabGroup, LabGroupMember
from thermolab.lab.db.models import Course, User

__all__ = ["MAX_GROUP", "GroupService", "group_of", "mates"]

#: The most students in one lab group.
MAX_GROUP = 12


class GroupService:
    """Form, list and remove a course's lab groups.

    Parameters
    ----------
    db : Database
    clock : LabClock
    """

    def __init__(self, db: Database, clock: LabClock) -> None:
        self._db = db
        self._clock = clock

    def create(self, course: str, who: Principal, name: str, members: Sequence[str]) -> GroupInfo:
        """Form the group ``name`` of ``members`` (students of ``course``, in no other group).

        Raises
        ------
        AccessDeniedError
            Not a teacher of the course.
        NotFoundError
            No such course, or a member who is not one of its students.
        InvalidParameterError
            A bad name, or fewer than two (or more than :data:`MAX_GROUP`) members.
        ConflictError
            The name is taken in the course, a member is in another group, or
            the course is closed.
        """
        title = " ".join(name.split())
        if not 0 < len(title) <= 64:
            raise InvalidParameterError("a group's name must have 1 to 64 characters")
        wanted = sorted({m.strip().lower() for m in members})
        if not 2 <= len(wanted) <= MAX_GROUP:
            raise InvalidParameterError(f"a lab group has 2 to {MAX_GROUP} different students")
        now = self._clock.now()
        try:
            with self._db.write() as session:
                found = course_named(session, course)
                require_in_course(session, found, who, Action.COURSE_GROUPS)
                require_open(found, "form lab groups")
                people = [course_student(session, found, m) for m in wanted]
                taken = session.scalar(
                    select(LabGroup.id).where(
                        LabGroup.course_id == found.id, LabGroup.name == title
                    )
                )
                if taken is not None:
                    raise ConflictError(
                        f"course {found.name!r} has a group called {title!r}",
                        case="group_name_taken",
                    )
                busy = session.execute(
                    select(User.username, LabGroup.name)
                    .join(LabGroupMember, LabGroupMember.user_id == User.id)
                    .join(LabGroup, LabGroup.id == LabGroupMember.group_id)
                    .where(
                        LabGroupMember.course_id == found.id,
                        LabGroupMember.user_id.in_([p.id for p in people]),
                    )
                    .order_by(User.username)
                ).all()
                if busy:
                    listed = ", ".join(f"{u} ({g})" for u, g in busy)
                    raise ConflictError(
                        f"already in a lab group of this course: {listed}", case="already_in_group"
                    )
                group = LabGroup(course_id=found.id, name=title, created_by=who.username)
                group.created_at = now
                session.add(group)
                session.flush()
                session.add_all(
                    LabGroupMember(group_id=group.id, course_id=found.id, user_id=p.id)
                    for p in people
                )
                session.flush()
                return _group_info(session, found, group)
        except IntegrityError:
            raise ConflictError(
                "the course's groups changed meanwhile; look at them again and retry",
                case="stored_meanwhile",
            ) from None

    def list(self, course: str, who: Principal) -> list[GroupInfo]:
        """The course's groups by name (its teachers and assistants)."""
        with self._db.read() as session:
            found = course_named(session, course)
            require_in_course(session, found, who, Action.COURSE_HAND_INS)
            groups = session.scalars(
                select(LabGroup).where(LabGroup.course_id == found.id).order_by(LabGroup.name)
            )
            return [_group_info(session, found, g) for g in groups]

    def remove(self, course: str, who: Principal, group_id: int) -> GroupInfo:
        """Remove a group (its members' hand-ins stay); return what it was."""
        with self._db.write() as session:
            found = course_named(session, course)
            require_in_course(session, found, who, Action.COURSE_GROUPS)
            require_open(found, "remove lab groups")
            group = session.get(LabGroup, group_id)
            if group is None or group.course_id != found.id:
                raise NotFoundError(f"course {found.name!r} has no lab group {group_id}")
            gone = _group_info(session, found, group)
            session.execute(delete(LabGroupMember).where(LabGroupMember.group_id == group.id))
            session.delete(group)
            return gone


def group_of(session: Session, course: Course, user_id: int) -> GroupInfo | None:
    """The student's lab group in ``course``, or ``None``."""
    group = session.scalar(
        select(LabGroup)
        .join(LabGroupMember, LabGroupMember.group_id == LabGroup.id)
        .where(LabGroupMember.course_id == course.id, LabGroupMember.user_id == user_id)
    )
    return None if group is None else _group_info(session, course, group)


def mates(session: Session, course_id: int, user_id: int) -> list[tuple[int, str]]:
    """``(user_id, username)`` of the student's group, themself included (alone: only them)."""
    group = select(LabGroupMember.group_id).where(
        LabGroupMember.course_id == course_id, LabGroupMember.user_id == user_id
    )
    found = session.execute(
        select(User.id, User.username)
        .join(LabGroupMember, LabGroupMember.user_id == User.id)
        .where(LabGroupMember.group_id.in_(group))
        .order_by(User.username)
    ).all()
    if not found:
        name = session.scalar(select(User.username).where(User.id == user_id))
        return [(user_id, name or "")]
    return [(i, n) for i, n in found]


def _group_info(session: Session, course: Course, group: LabGroup) -> GroupInfo:
    members = session.execute(
        select(User.username, User.display_name)
        .join(LabGroupMember, LabGroupMember.user_id == User.id)
        .where(LabGroupMember.group_id == group.id)
        .order_by(User.username)
    ).all()
    created: datetime = group.created_at
    return GroupInfo(
        group.id,
        course.name,
        group.name,
        tuple((u, d) for u, d in members),
        group.created_by,
        created,
    )
