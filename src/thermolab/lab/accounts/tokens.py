"""Personal API tokens: how scripts (``thermolab.client``, ``thermolab.tclab``) log in.

A user creates a token in the browser (or with ``POST /api/tokens`` from a
login session) and gives it to a script, which sends it as ``Authorization:
Bearer <token>`` on HTTP and on the live WebSocket's handshake. The token
acts as its user, with the user's rights (a teacher's token is a teacher's),
optionally read-only (GET only). The secret is shown once: the table keeps
its SHA-256, like a login's cookie token (random 256 bits, so a fast hash is
right; see :mod:`thermolab.lab.accounts.security`). Revoking deletes the row, so the
next request with the token is refused, and the lab announces the revoked
ids so that the live stream closes that token's sockets at once.

What a token cannot do, by design: change a password (the re-authentication
rule stays: only a password login with the current password may) and create
another token (a read-only token must not mint a full one).
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import delete, func, select

from thermolab.errors import ConflictError, InvalidParameterError, NotFoundError
from thermolab.lab.accounts.security import hash_token
from thermolab.lab.accounts.users import LoginsEnded, Principal
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.login_models import ApiToken
from thermolab.lab.db.models import Role, User

__all__ = [
    "DEFAULT_TOKEN_DAYS",
    "MAX_TOKENS_PER_USER",
    "MAX_TOKEN_DAYS",
    "MAX_TOKEN_NAME",
    "TOKEN_PREFIX",
    "NewToken",
    "TokenInfo",
    "TokenService",
]

TOKEN_PREFIX = "tlab_"
"""Every secret starts with this, so a leaked one is recognisable (secret scanners, logs)."""
DEFAULT_TOKEN_DAYS = 90
MAX_TOKEN_DAYS = 365
MAX_TOKENS_PER_USER = 20
MAX_TOKEN_NAME = 64
_SHOWN_PREFIX = 12  # characters of the secret kept to tell tokens apart in a list
_TOUCH_INTERVAL = timedelta(seconds=60)  # last use is rewritten at most this often


@dataclass(frozen=True, slots=True)
class TokenInfo:
    """A token as its owner sees it (never the secret).

    Attributes
    ----------
    id : int
    name : str
        The owner's label ("course notebook").
    prefix : str
        The secret's first characters, to recognise it.
    read_only : bool
    created_at, last_used_at, expires_at : datetime
    """

    id: int
    name: str
    prefix: str
    read_only: bool
    created_at: datetime
    last_used_at: datetime | None
    expires_at: datetime | None

    @classmethod
    def of(cls, row: ApiToken) -> TokenInfo:
        """Build from an :class:`~thermolab.lab.db.login_models.ApiToken` row."""
        return cls(
            row.id,
            row.name,
            row.prefix,
            row.read_only,
            row.created_at,
            row.last_used_at,
            row.expires_at,
        )


@dataclass(frozen=True, slots=True)
class NewToken:
    """A token just created: the secret (shown this once) and its description."""

    secret: str
    info: TokenInfo


def _check_name(name: str) -> str:
    text = " ".join(name.split())
    if not text or len(text) > MAX_TOKEN_NAME:
        raise InvalidParameterError(
            f"a token's name must have 1 to {MAX_TOKEN_NAME} characters (not only spaces)"
        )
    return text


class TokenService:
    """Create, list, revoke and resolve personal API tokens.

    Parameters
    ----------
    db : Database
    clock : LabClock
    revoked : LoginsEnded, optional
        Where the ids of revoked tokens are announced (the live stream closes
        their sockets).
    """

    def __init__(self, db: Database, clock: LabClock, *, revoked: LoginsEnded | None = None):
        self._db = db
        self._clock = clock
        self.revoked = revoked or LoginsEnded()

    def create(
        self,
        who: Principal,
        name: str,
        *,
        read_only: bool = False,
        days: int = DEFAULT_TOKEN_DAYS,
    ) -> NewToken:
        """Create a token for ``who`` (a password login: a token may not create tokens).

        Raises
        ------
        InvalidParameterError
            For a bad name or lifetime.
        ConflictError
            When the user already has :data:`MAX_TOKENS_PER_USER` tokens.
        """
        label = _check_name(name)
        if isinstance(days, bool) or not isinstance(days, int) or not 1 <= days <= MAX_TOKEN_DAYS:
            raise InvalidParameterError(f"a token lasts 1 to {MAX_TOKEN_DAYS} days; got {days!r}")
        secret = TOKEN_PREFIX + secrets.token_urlsafe(32)
        now = self._clock.now()
        with self._db.write() as session:
            count = session.scalar(
                select(func.count()).select_from(ApiToken).where(ApiToken.user_id == who.user_id)
            )
            if (count or 0) >= MAX_TOKENS_PER_USER:
                raise ConflictError(
                    f"you already have {MAX_TOKENS_PER_USER} tokens; revoke one first",
                    case="token_limit",
                )
            row = ApiToken(
                token_hash=hash_token(secret),
                user_id=who.user_id,
                name=label,
                prefix=secret[:_SHOWN_PREFIX],
                read_only=read_only,
                created_at=now,
                last_used_at=None,
                expires_at=now + timedelta(days=days),
            )
            session.add(row)
            session.flush()
            return NewToken(secret, TokenInfo.of(row))

    def of_user(self, who: Principal) -> list[TokenInfo]:
        """Return the user's tokens, newest first."""
        with self._db.read() as session:
            rows = session.scalars(
                select(ApiToken).where(ApiToken.user_id == who.user_id).order_by(ApiToken.id.desc())
            )
            return [TokenInfo.of(row) for row in rows]

    def revoke(self, who: Principal, token_id: int) -> None:
        """Revoke one of the user's own tokens; its open connections are closed at once.

        Raises
        ------
        NotFoundError
            If the user has no token with that id.
        """
        with self._db.write() as session:
            row = session.get(ApiToken, token_id)
            if row is None or row.user_id != who.user_id:
                raise NotFoundError(f"you have no token number {token_id}")
            session.delete(row)
        self.revoked.publish([token_id])

    def ids_of(self, user_id: int) -> list[int]:
        """Return the ids of a user's tokens (announced as revoked when the account goes)."""
        with self._db.read() as session:
            return list(session.scalars(select(ApiToken.id).where(ApiToken.user_id == user_id)))

    def resolve(self, secret: str | None) -> Principal | None:
        """Return the user a token acts as, or ``None`` for an unknown, revoked or expired one."""
        if not secret or len(secret) > 128 or not secret.startswith(TOKEN_PREFIX):
            return None
        now = self._clock.now()
        with self._db.read() as session:
            found = session.execute(
                select(ApiToken, User)
                .join(User, User.id == ApiToken.user_id)
                .where(ApiToken.token_hash == hash_token(secret))
            ).one_or_none()
            if found is None:
                return None
            token, user = found
            if token.expires_at is not None and now >= token.expires_at:
                return None
            stale = token.last_used_at is None or now - token.last_used_at >= _TOUCH_INTERVAL
            principal = Principal(
                user.id,
                user.username,
                Role(user.role),
                None,
                token.expires_at,
                token_id=token.id,
                read_only=token.read_only,
                admin=bool(user.admin),
            )
        if stale:
            with self._db.write() as session:
                row = session.get(ApiToken, principal.token_id)
                if row is not None:
                    row.last_used_at = now
        return principal

    def alive(self, token_ids: set[int]) -> set[int]:
        """Return which of ``token_ids`` still exist and have not expired."""
        if not token_ids:
            return set()
        now = self._clock.now()
        with self._db.read() as session:
            rows = session.execute(
                select(ApiToken.id, ApiToken.expires_at).where(ApiToken.id.in_(token_ids))
            )
            return {i for i, ends in rows if ends is None or ends > now}

    def purge_expired(self) -> int:
        """Delete expired tokens; return how many."""
        now = self._clock.now()
        with self._db.write() as session:
            which = ApiToken.expires_at <= now
            ended = list(session.scalars(select(ApiToken.id).where(which)))
            session.execute(delete(ApiToken).where(ApiToken.id.in_(ended)))
        self.revoked.publish(ended)
        return len(ended)
