"""Login sessions: a user name and password into a server-side session, a cookie
token back into the user it belongs to (:class:`SessionService`).

Accounts and the :class:`~thermolab.lab.accounts.users.LoginsEnded` event every ended
login is announced on are :mod:`thermolab.lab.accounts.users`.
"""

from __future__ import annotations

from datetime import timedelta

from sqlalchemy import delete, select

from thermolab.lab.accounts.security import hash_token, new_token
from thermolab.lab.accounts.users import LoginsEnded, Principal, UserInfo
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.login_models import LoginSession
from thermolab.lab.db.models import Role, User

__all__ = ["SessionService"]

# A last-seen time is rewritten at most this often, so that reads stay reads.
_TOUCH_INTERVAL = timedelta(seconds=60)


class SessionService:
    """Server-side login sessions.

    Parameters
    ----------
    db : Database
    clock : LabClock
    lifetime : float
        Seconds a session lasts at most.
    idle_timeout : float
        Seconds without a request after which a session ends.
    logins_ended : LoginsEnded, optional
        Where ended sessions are announced.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        *,
        lifetime: float,
        idle_timeout: float,
        logins_ended: LoginsEnded | None = None,
    ) -> None:
        self._db = db
        self._ended = logins_ended or LoginsEnded()
        self._clock = clock
        self._lifetime = timedelta(seconds=lifetime)
        self._idle = timedelta(seconds=idle_timeout)

    def create(
        self, user: UserInfo, *, client_address: str | None = None, user_agent: str | None = None
    ) -> tuple[str, Principal]:
        """Open a session for ``user``; return the token for the cookie and the principal."""
        token = new_token()
        now = self._clock.now()
        with self._db.write() as session:
            row = LoginSession(
                token_hash=hash_token(token),
                user_id=user.id,
                created_at=now,
                last_seen_at=now,
                expires_at=now + self._lifetime,
                client_address=(client_address or None) and client_address[:64],
                user_agent=(user_agent or None) and user_agent[:256],
            )
            session.add(row)
            session.flush()
            return token, Principal(
                user.id,
                user.username,
                user.role,
                row.id,
                row.expires_at,
                must_change_password=user.must_change_password,
                admin=bool(user.admin),
            )

    def resolve(self, token: str | None) -> Principal | None:
        """Return who a cookie token belongs to, or ``None`` if it is not a live session."""
        if not token or len(token) > 128:
            return None
        digest = hash_token(token)
        now = self._clock.now()
        with self._db.read() as session:
            found = session.execute(
                select(LoginSession, User)
                .join(User, User.id == LoginSession.user_id)
                .where(LoginSession.token_hash == digest)
            ).one_or_none()
            if found is None:
                return None
            login, user = found
            expired = now >= login.expires_at or now - login.last_seen_at >= self._idle
            stale = now - login.last_seen_at >= _TOUCH_INTERVAL
            principal = Principal(
                user.id,
                user.username,
                Role(user.role),
                login.id,
                login.expires_at,
                must_change_password=bool(user.must_change_password),
                admin=bool(user.admin),
            )
        if expired:
            self.end(token)
            return None
        if stale:
            with self._db.write() as session:
                row = session.get(LoginSession, principal.session_id)
                if row is not None:
                    row.last_seen_at = now
        return principal

    def end(self, token: str | None) -> None:
        """End the session of ``token`` (no error if there is none)."""
        if not token:
            return
        digest = hash_token(token)
        with self._db.write() as session:
            which = LoginSession.token_hash == digest
            ended = list(session.scalars(select(LoginSession.id).where(which)))
            session.execute(delete(LoginSession).where(which))
        self._ended.publish(ended)

    def purge_expired(self) -> int:
        """Delete expired sessions; return how many."""
        now = self._clock.now()
        which = (LoginSession.expires_at <= now) | (LoginSession.last_seen_at <= now - self._idle)
        with self._db.write() as session:
            ended = list(session.scalars(select(LoginSession.id).where(which)))
            session.execute(delete(LoginSession).where(LoginSession.id.in_(ended)))
        self._ended.publish(ended)
        return len(ended)
