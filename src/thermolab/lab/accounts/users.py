"""User accounts: who someone is (:class:`Principal`) and what logins end.

:class:`UserService` keeps accounts (the ``thermolab user`` command and the
teachers' API use it); :class:`LoginsEnded` is the event every ended login is
announced on. The login sessions themselves (a password into a session, a
cookie token back into its user) are :mod:`thermolab.lab.accounts.login_sessions`.
Both work on the :class:`~thermolab.lab.db.Database` directly, so the
command line can manage accounts while the server runs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import datetime

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError
from sqlalchemy import delete, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    InvalidParameterError,
    NameTakenError,
    NotFoundError,
)
from thermolab.lab.accounts.names import normalize_display_name
from thermolab.lab.accounts.security import (
    MAX_PASSWORD_LENGTH,
    AuthenticationError,
    normalize_username,
    validate_password,
)
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.login_models import LoginSession
from thermolab.lab.db.models import ControlSession, QueueEntry, Role, TurnEndReason, User

__all__ = [
    "LoginsEnded",
    "Principal",
    "UserInfo",
    "UserService",
    "parse_role",
    "user_named",
]


def parse_role(role: str) -> Role:
    """Return the :class:`~thermolab.lab.db.models.Role` called ``role``.

    Raises
    ------
    InvalidParameterError
        If it is not ``student`` or ``teacher``.

    Examples
    --------
    >>> parse_role("teacher")
    <Role.TEACHER: 'teacher'>
    """
    try:
        return Role(role)
    except ValueError:
        raise InvalidParameterError(
            f"role {role!r} is not known; use 'student', 'teacher' or 'admin'"
        ) from None


@dataclass(frozen=True, slots=True)
class UserInfo:
    """An account, without its password hash.

    Attributes
    ----------
    id : int
    username : str
    role : Role
    created_at : datetime
    display_name : str or None
        The name as the person writes it (``João da Silva``), if given.
    must_change_password : bool
        The password is a temporary one (a class list's or a teacher's reset).
    admin : bool
        A lab administrator (a teacher who also manages what spans courses).
    """

    id: int
    username: str
    role: Role
    created_at: datetime
    display_name: str | None = None
    must_change_password: bool = False
    admin: bool = False

    @classmethod
    def of(cls, user: User) -> UserInfo:
        """Build from a :class:`~thermolab.lab.db.models.User` row."""
        return cls(
            user.id,
            user.username,
            Role(user.role),
            user.created_at,
            user.display_name,
            bool(user.must_change_password),
            bool(user.admin),
        )


@dataclass(frozen=True, slots=True)
class Principal:
    """The user behind a request, and the login session it came with.

    Attributes
    ----------
    user_id : int
    username : str
    role : Role
    session_id : int or None
        The login session (``None`` for work done outside a request).
    expires_at : datetime or None
        When the login session (or the API token) ends at the latest.
    token_id : int or None
        The personal API token the request came with (``session_id`` is then
        ``None``): see :mod:`thermolab.lab.accounts.tokens`.
    read_only : bool
        A read-only token: it may only read (GET), never change anything.
    must_change_password : bool
        The login was made with a temporary password: only changing it is allowed.
    admin : bool
        A lab administrator (see :mod:`thermolab.lab.accounts.policy`).
    """

    user_id: int
    username: str
    role: Role
    session_id: int | None = None
    expires_at: datetime | None = None
    token_id: int | None = None
    read_only: bool = False
    must_change_password: bool = False
    admin: bool = False

    @property
    def login_key(self) -> tuple[str, int | None]:
        """What this principal logged in with: ``("session", id)`` or ``("token", id)``."""
        if self.token_id is not None:
            return ("token", self.token_id)
        return ("session", self.session_id)

    @property
    def is_teacher(self) -> bool:
        """``True`` for a teacher (an administrator is one too)."""
        return self.role is Role.TEACHER

    @property
    def is_admin(self) -> bool:
        """``True`` for a lab administrator."""
        return self.admin and self.role is Role.TEACHER

    def require_teacher(self, action: str) -> None:
        """Refuse ``action`` (words after "may") unless this is a teacher.

        Raises
        ------
        AccessDeniedError
            For a student.
        """
        if not self.is_teacher:
            raise AccessDeniedError(f"only a teacher may {action}")


class UserService:
    """Create, list, change and remove accounts.

    Parameters
    ----------
    db : Database
    clock : LabClock
    hasher : PasswordHasher
        Argon2 hasher (tests pass a cheap one).
    logins_ended : LoginsEnded, optional
        Where the logins a new password or a removed account ends are announced.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        hasher: PasswordHasher,
        *,
        logins_ended: LoginsEnded | None = None,
    ) -> None:
        self._ended = logins_ended or LoginsEnded()
        self._db = db
        self._clock = clock
        self._hasher = hasher

    def add(
        self,
        username: str,
        password: str,
        role: Role | str,
        display_name: str | None = None,
        *,
        admin: bool = False,
    ) -> UserInfo:
        """Create an account.

        ``username`` is stored in its normal form (``joão`` and ``JOAO`` are
        both ``joao``); ``display_name`` as written (``João da Silva``).
        ``admin`` makes a teacher a lab administrator.

        Raises
        ------
        InvalidParameterError
            For a bad user name, display name, password or role.
        NameTakenError
            If the user name, in its normal form, is taken (409 ``name_taken``).
        """
        name = normalize_username(username)
        shown = None if display_name is None else normalize_display_name(display_name)
        role = parse_role(role) if isinstance(role, str) else role
        if admin and role is not Role.TEACHER:
            raise InvalidParameterError("only a teacher can be a lab administrator")
        password_hash = self._hasher.hash(validate_password(password, name))
        now = self._clock.now()
        try:
            with self._db.write() as session:
                if session.scalar(select(User.id).where(User.username == name)) is not None:
                    raise NameTakenError("taken.user", name)
                user = User(
                    username=name,
                    display_name=shown,
                    role=role.value,
                    password_hash=password_hash,
                    created_at=now,
                    password_changed_at=now,
                    admin=admin,
                )
                session.add(user)
                session.flush()
                return UserInfo.of(user)
        except IntegrityError:
            raise NameTakenError("taken.user", name) from None

    def get(self, username: str) -> UserInfo:
        """Return the account called ``username``.

        Raises
        ------
        NotFoundError
            If there is none.
        """
        with self._db.read() as session:
            return UserInfo.of(user_named(session, username))

    def list(self) -> list[UserInfo]:
        """Return every account, by user name."""
        with self._db.read() as session:
            return [UserInfo.of(u) for u in session.scalars(select(User).order_by(User.username))]

    def set_admin(self, username: str, admin: bool) -> UserInfo:
        """Make a teacher a lab administrator (``admin``) or take it back.

        Raises
        ------
        NotFoundError
            If there is no such user.
        InvalidParameterError
            For a student, or taking back the last administrator.
        """
        with self._db.write() as session:
            user = user_named(session, username)
            if admin and user.role != Role.TEACHER.value:
                raise InvalidParameterError("only a teacher can be a lab administrator")
            if not admin and user.admin:
                others = session.scalar(
                    select(func.count())
                    .select_from(User)
                    .where(User.admin.is_(True), User.id != user.id)
                )
                if not others:
                    raise InvalidParameterError(
                        "this is the lab's last administrator; make another one first"
                    )
            user.admin = admin
            session.flush()
            return UserInfo.of(user)

    def count_teachers(self) -> int:
        """Return how many teacher accounts exist."""
        with self._db.read() as session:
            return (
                session.scalar(
                    select(func.count()).select_from(User).where(User.role == Role.TEACHER.value)
                )
                or 0
            )

    def set_password(
        self, username: str, password: str, *, keep_session: int | None = None
    ) -> None:
        """Change a password; every login of the user ends but ``keep_session``.

        Raises
        ------
        NotFoundError
            If there is no such user.
        InvalidParameterError
            If the password does not meet
            :func:`~thermolab.lab.accounts.security.validate_password`.
        """
        password_hash = self._hasher.hash(validate_password(password, username))
        with self._db.write() as session:
            user = user_named(session, username)
            user.password_hash = password_hash
            user.password_changed_at = self._clock.now()
            user.must_change_password = False
            which = (LoginSession.user_id == user.id) & (LoginSession.id != (keep_session or -1))
            ended = list(session.scalars(select(LoginSession.id).where(which)))
            session.execute(delete(LoginSession).where(which))
        self._ended.publish(ended)

    def remove(self, username: str) -> UserInfo:
        """Remove an account with its logins, queue places and runs.

        A control session the user holds ends (reason ``kicked``, by "account
        removed"); the lab hands the rig to the next in the queue at its next
        look at the rig. The lab's history of who used which rig keeps the
        name.

        Raises
        ------
        NotFoundError
            If there is no such user.
        """
        now = self._clock.now()
        with self._db.write() as session:
            user = user_named(session, username)
            rig_ids = set(
                session.scalars(
                    select(ControlSession.rig_id).where(
                        ControlSession.user_id == user.id, ControlSession.ended_at.is_(None)
                    )
                )
            ) | set(
                session.scalars(
                    select(QueueEntry.rig_id).where(
                        QueueEntry.user_id == user.id, QueueEntry.left_at.is_(None)
                    )
                )
            )
            # Same lock order as everyone else (rig rows, sorted) so that no deadlock is possible.
            for rig_id in sorted(rig_ids):
                self._db.lock_rig(session, rig_id)
            for control in session.scalars(
                select(ControlSession).where(
                    ControlSession.user_id == user.id, ControlSession.ended_at.is_(None)
                )
            ):
                control.ended_at = now
                control.end_reason = TurnEndReason.KICKED.value
                control.ended_by = "account removed"
            info = UserInfo.of(user)
            ended = list(
                session.scalars(select(LoginSession.id).where(LoginSession.user_id == user.id))
            )
            session.delete(user)
        self._ended.publish(ended)
        return info

    def verify(self, username: str, password: str) -> UserInfo:
        """Check a user name and password.

        Raises
        ------
        AuthenticationError
            If either is wrong (the message does not say which).
        """
        try:
            name = normalize_username(username)
        except InvalidParameterError:
            name = None
        with self._db.read() as session:
            user = (
                session.scalars(select(User).where(User.username == name)).one_or_none()
                if name is not None
                else None
            )
            stored = user.password_hash if user is not None else None
        ok = False
        if len(password) <= MAX_PASSWORD_LENGTH:
            try:
                # Hash even for an unknown user, so timing does not tell which names exist.
                ok = self._hasher.verify(stored or _DUMMY_HASH.get(self._hasher), password)
            except (VerificationError, InvalidHashError):
                ok = False
        if user is None or stored is None or not ok:
            raise AuthenticationError("wrong user name or password")
        if self._hasher.check_needs_rehash(stored):
            with self._db.write() as session:
                row = session.get(User, user.id)
                if row is not None and row.password_hash == stored:
                    row.password_hash = self._hasher.hash(password)
        return UserInfo.of(user)


class _DummyHashes:
    """One throw-away hash per hasher, verified against when the user is unknown."""

    def __init__(self) -> None:
        self._hashes: dict[int, str] = {}

    def get(self, hasher: PasswordHasher) -> str:
        key = id(hasher)
        if key not in self._hashes:
            self._hashes[key] = hasher.hash("not a password anyone has")
        return self._hashes[key]


_DUMMY_HASH = _DummyHashes()


class LoginsEnded:
    """The event "these logins have ended", for whoever listens (the live stream).

    Published after the change is committed, from the thread that made it,
    with the ids of the login sessions that ended (logout, expiry, a new
    password, a removed account).

    Examples
    --------
    >>> seen = []
    >>> event = LoginsEnded()
    >>> event.subscribe(seen.append)
    >>> event.publish([3, 4])
    >>> event.publish([])
    >>> seen
    [frozenset({3, 4})]
    """

    def __init__(self) -> None:
        self._listeners: list[Callable[[frozenset[int]], None]] = []

    def subscribe(self, listener: Callable[[frozenset[int]], None]) -> None:
        """Call ``listener`` with the ids of every batch of logins that ends."""
        self._listeners.append(listener)

    def publish(self, session_ids: Iterable[int]) -> None:
        """Announce that ``session_ids`` ended (nothing for none)."""
        ended = frozenset(session_ids)
        if ended:
            for listener in list(self._listeners):
                listener(ended)


def user_named(session: Session, username: str) -> User:
    """The account called ``username`` (as typed: normalised when it can be).

    Raises
    ------
    NotFoundError
        No such account.
    """
    try:
        name = normalize_username(username)
    except InvalidParameterError:
        name = username
    user = session.scalars(select(User).where(User.username == name)).one_or_none()
    if user is None:
        raise NotFoundError(f"no user called {username!r}")
    return user
