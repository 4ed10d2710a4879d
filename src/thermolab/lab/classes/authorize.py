"""The policy table (:mod:`thermolab.lab.accounts.policy`) checked against the courses.

:class:`Authorizer` answers "may this person do this to that course, or to
that person?" with one query: a teacher's ``taught`` scope is the courses
where they are a ``teacher`` member, and a person in it is a student of one
of those courses (never another teacher, whose password is an
administrator's business). A teaching assistant reaches, for the actions the
table gives assistants, the courses where they are an ``assistant`` member,
whatever their account's kind.

A run is its owner's to read, any teacher's, and — read only — a lab group
mate's (:func:`reads_as_group_mate`): the one exception to "a student reads
only their own runs", decided here and asked by the run store.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from thermolab.errors import AccessDeniedError, NotFoundError
from thermolab.lab.accounts.policy import (
    POLICY,
    Action,
    Actor,
    Scope,
    assists,
    member_reaches,
    require_lab,
    scope_of,
    who_may,
)
from thermolab.lab.accounts.security import normalize_username
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db import Database
from thermolab.lab.db.assignment_models import Assignment, Submission
from thermolab.lab.db.grading_models import LabGroup, LabGroupMember
from thermolab.lab.db.models import Course, CourseMember, MemberRole, Role, Run, User

__all__ = ["Authorizer", "reads_as_group_mate", "require_in_course"]


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
            When the table gives ``who`` no scope for ``action``, and ``who``
            assists no course where assistants may.
        """
        if scope_of(who, action) is not Scope.NONE:
            return
        if assists(action):
            with self._db.read() as session:
                if _assists_any(session, who.user_id):
                    return
        reach = (Scope.LAB, Scope.TAUGHT, Scope.SELF)
        raise AccessDeniedError(f"only {who_may(action, reach)} may {action}")

    def require_lab(self, who: Principal, action: Action) -> None:
        """Refuse ``action`` unless ``who`` may do it lab-wide (an administrator's)."""
        require_lab(who, action)

    def require_course(self, who: Principal, action: Action, course: str) -> None:
        """Refuse ``action`` on ``course`` unless ``who`` reaches it.

        Raises
        ------
        AccessDeniedError
            Naming the course, for a teacher who does not teach it (or assist
            it, where assistants may).
        NotFoundError
            For an unknown course, to a teacher (who could act on it if it existed).
        """
        scope = scope_of(who, action)
        if scope is Scope.LAB:
            return
        helpers = " or a teaching assistant" if assists(action) else ""
        refused = AccessDeniedError(
            f"only a teacher{helpers} of course {course!r} (or a lab administrator) may {action}"
        )
        if scope is not Scope.TAUGHT and not assists(action):
            if POLICY[action][Actor.TEACHER] is not Scope.TAUGHT:
                require_lab(who, action)
            raise refused
        with self._db.read() as session:
            found = session.scalar(select(Course.id).where(Course.name == course.strip().lower()))
            if found is None and scope is Scope.TAUGHT:
                raise NotFoundError(f"no course called {course!r}")
            if found is None or not member_reaches(who, action, _held(session, who.user_id, found)):
                raise refused

    def taught(self, who: Principal, action: Action) -> frozenset[str] | None:
        """Return the names of the courses ``who`` may ``action`` (``None``: every course)."""
        scope = scope_of(who, action)
        if scope is Scope.LAB:
            return None
        places = [MemberRole.TEACHER.value] if scope is Scope.TAUGHT else []
        if assists(action):
            places.append(MemberRole.ASSISTANT.value)
        if not places:
            return frozenset()
        with self._db.read() as session:
            return frozenset(
                session.scalars(
                    select(Course.name)
                    .join(CourseMember, CourseMember.course_id == Course.id)
                    .where(CourseMember.user_id == who.user_id, CourseMember.role.in_(places))
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


def require_in_course(session: Session, course: Course, who: Principal, action: Action) -> None:
    """Refuse ``action`` on ``course`` (a row read in the caller's transaction) unless
    ``who`` reaches it: :meth:`Authorizer.require_course` inside a service's transaction.

    Raises
    ------
    AccessDeniedError
        Naming the course.
    """
    if scope_of(who, action) is Scope.LAB:
        return
    if not member_reaches(who, action, _held(session, who.user_id, course.id)):
        helpers = " or a teaching assistant" if assists(action) else ""
        raise AccessDeniedError(
            f"only a teacher{helpers} of course {course.name!r} may {action}; "
            "ask one of its teachers to add you"
        )


def reads_as_group_mate(session: Session, run: Run, who: Principal) -> bool:
    """Whether the student ``who`` may read (only read) ``run``, a lab group mate's.

    The least reach that makes a group's shared run usable: ``who`` and the
    run's owner are, now, students of one course and members of one lab
    group of it, and the run was started once the group was formed (the
    group's work at the rig) or is one of ``who``'s own hand-ins in that
    course (a mate handed it in for the group). Earlier runs of a mate, and
    any run once the group is removed or either leaves the course, stay the
    owner's. Reading never lets a mate control, end or hand in beyond what
    the group's hand-in already allows.
    """
    if run.user_id == who.user_id:
        return False
    mine = select(LabGroupMember.group_id).where(LabGroupMember.user_id == who.user_id)
    shared = session.execute(
        select(LabGroup.course_id, LabGroup.created_at)
        .join(LabGroupMember, LabGroupMember.group_id == LabGroup.id)
        .where(LabGroupMember.user_id == run.user_id, LabGroup.id.in_(mine))
    ).all()  # a group of each course the two share groups in
    return any(_mates_run(session, run, who, course, formed) for course, formed in shared)


def _mates_run(
    session: Session, run: Run, who: Principal, course_id: int, formed: datetime
) -> bool:
    # Both still students of the group's course: one who left it reads no more.
    students = session.scalar(
        select(func.count(CourseMember.id)).where(
            CourseMember.course_id == course_id,
            CourseMember.role == MemberRole.STUDENT.value,
            CourseMember.user_id.in_((who.user_id, run.user_id)),
        )
    )
    if students != 2:
        return False
    if run.started_at >= formed:
        return True
    handed_in = session.scalar(
        select(Submission.id)
        .join(Assignment, Assignment.id == Submission.assignment_id)
        .where(
            Submission.user_id == who.user_id,
            Submission.run_id == run.id,
            Assignment.course_id == course_id,
        )
        .limit(1)
    )
    return handed_in is not None


def _held(session: Session, user_id: int, course_id: int) -> str | None:
    """The user's place in the course (``None``: not in it)."""
    return session.scalar(
        select(CourseMember.role).where(
            CourseMember.course_id == course_id, CourseMember.user_id == user_id
        )
    )


def _assists_any(session: Session, user_id: int) -> bool:
    return (
        session.scalar(
            select(CourseMember.id).where(
                CourseMember.user_id == user_id,
                CourseMember.role == MemberRole.ASSISTANT.value,
            )
        )
        is not None
    )
