"""Courses and their people: teachers, students from a class list or an enrolment code.

:class:`CourseService` works on the database directly (the API and
``thermolab course`` use it). A class list is imported in one transaction:
new login names become student accounts with a temporary password (shown
once, to be changed at the first login), known ones get the list's display
name and join the course; a re-upload updates and never duplicates. A student
can instead enrol with the course's code, choosing a password. A teacher's
password reset gives a temporary password the same way.
"""

from __future__ import annotations

import builtins
import secrets
from dataclasses import dataclass, field
from datetime import datetime

from argon2 import PasswordHasher
from sqlalchemy import delete, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    ClassListError,
    ClassListProblem,
    ConflictError,
    CourseNameTakenError,
    NameTakenError,
    NotFoundError,
    WrongEnrolCodeError,
)
from thermolab.lab.accounts.names import normalize_display_name, normalize_username
from thermolab.lab.accounts.security import validate_password
from thermolab.lab.accounts.users import LoginsEnded, UserInfo
from thermolab.lab.classes.class_list import read_class_list
from thermolab.lab.classes.closed import require_open
from thermolab.lab.classes.course_access import course_named
from thermolab.lab.classes.course_names import course_name, course_title, new_enrol_code
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.login_models import LoginSession
from thermolab.lab.db.models import Course, CourseMember, CourseRig, MemberRole, Role, User

__all__ = [
    "CourseInfo",
    "CourseService",
    "ImportReport",
    "Member",
    "temporary_password",
]


def temporary_password() -> str:
    """A random one-time password (about 96 bits) that meets the password rules.

    It starts with a letter or digit: a spreadsheet would take a leading ``-`` for
    a formula (``#NAME?``) when a teacher opens the list of passwords.
    """
    while True:
        password = secrets.token_urlsafe(12)
        if not password[0].isalnum():
            continue
        try:
            return validate_password(password)
        except ValueError:  # pragma: no cover - a random 16-character string is never listed
            continue


@dataclass(frozen=True, slots=True)
class Member:
    """A person in a course."""

    username: str
    display_name: str | None
    role: MemberRole
    must_change_password: bool


@dataclass(frozen=True, slots=True)
class CourseInfo:
    """A course, its code, its rigs (empty: every rig) and, when asked, its roster."""

    name: str
    title: str
    enrol_code: str
    created_at: datetime
    rigs: tuple[str, ...]
    members: tuple[Member, ...] = ()
    #: When the course was closed for the term (``None``: open), and by whom.
    closed_at: datetime | None = None
    closed_by: str | None = None


@dataclass(slots=True)
class ImportReport:
    """What a class list changed: names created (with their one-time passwords), updated, kept."""

    created: dict[str, str] = field(default_factory=dict)
    updated: list[str] = field(default_factory=list)
    unchanged: list[str] = field(default_factory=list)
    #: How the file's bytes were read (``"UTF-8"``, ``"Windows-1252"``...).
    encoding: str = "UTF-8"


class CourseService:
    """Create courses, import class lists, enrol with a code, reset passwords.

    Parameters
    ----------
    db : Database
    clock : LabClock
    hasher : PasswordHasher
    logins_ended : LoginsEnded, optional
        Where the logins a password reset ends are announced.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        hasher: PasswordHasher,
        *,
        logins_ended: LoginsEnded | None = None,
    ) -> None:
        self._db = db
        self._clock = clock
        self._hasher = hasher
        self._ended = logins_ended or LoginsEnded()

    def create(self, name: str, title: str, teacher: str) -> CourseInfo:
        """Create a course with ``teacher`` as its first teacher.

        Raises
        ------
        InvalidParameterError
            A name other than 1–64 lower-case letters, digits, ``. _ -``, or an empty title.
        CourseNameTakenError
            If the name is taken.
        AccessDeniedError
            If ``teacher`` is a student's account.
        """
        name = course_name(name)
        title = course_title(title)
        now = self._clock.now()
        try:
            with self._db.write() as session:
                if session.scalar(select(Course.id).where(Course.name == name)) is not None:
                    raise CourseNameTakenError("taken.course", name)
                user = _user(session, teacher)
                if user.role != Role.TEACHER.value:
                    raise AccessDeniedError(f"{user.username!r} is not a teacher's account")
                course = Course(name=name, title=title, enrol_code=new_enrol_code(), created_at=now)
                session.add(course)
                session.flush()
                session.add(
                    CourseMember(
                        course_id=course.id, user_id=user.id, role=user.role, joined_at=now
                    )
                )
                session.flush()
                return _info(session, course, roster=True)
        except IntegrityError:
            raise CourseNameTakenError("taken.course", name) from None

    def list(self) -> list[CourseInfo]:
        """Every course, by name (without rosters)."""
        with self._db.read() as session:
            courses = session.scalars(select(Course).order_by(Course.name))
            return [_info(session, c, roster=False) for c in courses]

    def get(self, name: str) -> CourseInfo:
        """A course with its roster.

        Raises
        ------
        NotFoundError
        """
        with self._db.read() as session:
            return _info(session, course_named(session, name), roster=True)

    def rotate_code(self, name: str) -> str:
        """Give the course a new enrolment code (the old one stops working); return it."""
        with self._db.write() as session:
            course = course_named(session, name)
            require_open(course, "change its enrolment code")
            course.enrol_code = new_enrol_code()
            return course.enrol_code

    def set_rigs(self, name: str, rigs: builtins.list[str], known: set[str]) -> CourseInfo:
        """Set which rigs the course's students may use (empty: all of them).

        Raises
        ------
        NotFoundError
            For an unknown course or a rig not in ``known``.
        """
        unknown = sorted(set(rigs) - known)
        if unknown:
            raise NotFoundError(f"no rig called {unknown[0]!r}; rigs: {', '.join(sorted(known))}")
        with self._db.write() as session:
            course = course_named(session, name)
            require_open(course, "change its rigs")
            session.execute(delete(CourseRig).where(CourseRig.course_id == course.id))
            for rig in sorted(set(rigs)):
                session.add(CourseRig(course_id=course.id, rig_id=rig))
            session.flush()
            return _info(session, course, roster=True)

    def check_rig(self, user_id: int, rig: str) -> None:
        """Refuse a student a rig none of their courses allows.

        A student in no course, or in a course that lists no rigs, may use
        every rig; otherwise only the rigs one of their courses lists.

        Raises
        ------
        AccessDeniedError
        """
        with self._db.read() as session:
            courses = list(
                session.scalars(
                    select(CourseMember.course_id).where(
                        CourseMember.user_id == user_id, CourseMember.role == Role.STUDENT.value
                    )
                )
            )
            if not courses:
                return
            listed = session.execute(
                select(CourseRig.course_id, CourseRig.rig_id).where(
                    CourseRig.course_id.in_(courses)
                )
            ).all()
        limited = {course for course, _ in listed}
        if any(c not in limited for c in courses) or any(r == rig for _, r in listed):
            return
        raise AccessDeniedError(
            f"your courses do not use rig {rig!r}; ask your teacher which rigs are yours"
        )

    def import_class_list(self, name: str, data: bytes) -> ImportReport:
        """Add or update the students of a class list, all or nothing.

        Raises
        ------
        ClassListError
            For a malformed file, or a line naming a teacher's account (each line reported).
        NotFoundError
            For an unknown course.
        """
        read = read_class_list(data)
        entries = read.entries
        # Hashing is slow on purpose: done before the transaction, for the new names only.
        with self._db.read() as session:
            course = course_named(session, name)
            require_open(course, "upload a class list")
            course_id = course.id
            known = {
                u.username: u
                for u in session.scalars(
                    select(User).where(User.username.in_([e.username for e in entries]))
                )
            }
            teachers = [
                ClassListProblem.of(e.line, "class_list.teacher", value=repr(e.username))
                for e in entries
                if e.username in known and known[e.username].role == Role.TEACHER.value
            ]
        if teachers:
            raise ClassListError(teachers)
        report = ImportReport(encoding=read.encoding)
        hashes = {}
        for entry in entries:
            if entry.username not in known:
                password = temporary_password()
                report.created[entry.username] = password
                hashes[entry.username] = self._hasher.hash(password)
        now = self._clock.now()
        try:
            with self._db.write() as session:
                require_open(course_named(session, name), "upload a class list")
                members = set(
                    session.scalars(
                        select(CourseMember.user_id).where(CourseMember.course_id == course_id)
                    )
                )
                for entry in entries:
                    user = session.scalars(
                        select(User).where(User.username == entry.username)
                    ).one_or_none()
                    if user is None:
                        if entry.username not in hashes:
                            raise ConflictError(
                                f"{entry.username!r} was removed meanwhile",
                                case="class_list_changed",
                            )
                        user = User(
                            username=entry.username,
                            display_name=entry.display_name,
                            role=Role.STUDENT.value,
                            password_hash=hashes[entry.username],
                            created_at=now,
                            password_changed_at=now,
                            must_change_password=True,
                        )
                        session.add(user)
                        session.flush()
                    elif entry.username in report.created:
                        raise ConflictError(
                            f"{entry.username!r} was created meanwhile", case="class_list_changed"
                        )
                    elif user.display_name != entry.display_name or user.id not in members:
                        user.display_name = entry.display_name
                        report.updated.append(entry.username)
                    else:
                        report.unchanged.append(entry.username)
                    if user.id not in members:
                        session.add(
                            CourseMember(
                                course_id=course_id,
                                user_id=user.id,
                                role=Role.STUDENT.value,
                                joined_at=now,
                            )
                        )
                        members.add(user.id)
        except IntegrityError:
            raise ConflictError(
                "the accounts changed while importing; upload again", case="class_list_changed"
            ) from None
        return report

    def enrol(self, code: str, username: str, display_name: str, password: str) -> UserInfo:
        """Create a student account in the course whose code this is.

        Raises
        ------
        WrongEnrolCodeError
            No course has this code.
        InvalidParameterError
            A bad login name, display name or password.
        NameTakenError
            The login name is taken.
        """
        name = normalize_username(username)
        shown = normalize_display_name(display_name)
        password_hash = self._hasher.hash(validate_password(password, name))
        now = self._clock.now()
        try:
            with self._db.write() as session:
                course = session.scalars(
                    select(Course).where(Course.enrol_code == code.strip().upper())
                ).one_or_none()
                if course is None:
                    raise WrongEnrolCodeError("no course has this enrolment code; ask your teacher")
                require_open(course, "enrol")
                if session.scalar(select(User.id).where(User.username == name)) is not None:
                    raise NameTakenError("taken.user_choose", name)
                user = User(
                    username=name,
                    display_name=shown,
                    role=Role.STUDENT.value,
                    password_hash=password_hash,
                    created_at=now,
                    password_changed_at=now,
                    must_change_password=False,
                )
                session.add(user)
                session.flush()
                session.add(
                    CourseMember(
                        course_id=course.id, user_id=user.id, role=Role.STUDENT.value, joined_at=now
                    )
                )
                return UserInfo.of(user)
        except IntegrityError:
            raise NameTakenError("taken.user", name) from None

    def reset_password(self, username: str) -> str:
        """Give a student a temporary password (returned, to show once); their logins end.

        Raises
        ------
        NotFoundError
        AccessDeniedError
            For a teacher's account (a teacher changes their own).
        """
        password = temporary_password()
        password_hash = self._hasher.hash(password)
        with self._db.write() as session:
            user = _user(session, username)
            if user.role != Role.STUDENT.value:
                raise AccessDeniedError("only a student's password can be reset this way")
            user.password_hash = password_hash
            user.password_changed_at = self._clock.now()
            user.must_change_password = True
            which = LoginSession.user_id == user.id
            ended = list(session.scalars(select(LoginSession.id).where(which)))
            session.execute(delete(LoginSession).where(which))
        self._ended.publish(ended)
        return password


def _user(session: Session, username: str) -> User:
    user = session.scalars(
        select(User).where(User.username == normalize_username(username))
    ).one_or_none()
    if user is None:
        raise NotFoundError(f"no user called {username!r}")
    return user


def _info(session: Session, course: Course, *, roster: bool) -> CourseInfo:
    rigs = tuple(
        session.scalars(
            select(CourseRig.rig_id)
            .where(CourseRig.course_id == course.id)
            .order_by(CourseRig.rig_id)
        )
    )
    members: tuple[Member, ...] = ()
    if roster:
        rows = session.execute(
            select(User, CourseMember.role)
            .join(CourseMember, CourseMember.user_id == User.id)
            .where(CourseMember.course_id == course.id)
            .order_by(CourseMember.role.desc(), User.username)
        ).all()
        members = tuple(
            Member(u.username, u.display_name, MemberRole(role), bool(u.must_change_password))
            for u, role in rows
        )
    return CourseInfo(
        course.name,
        course.title,
        course.enrol_code,
        course.created_at,
        rigs,
        members,
        course.closed_at,
        course.closed_by,
    )
