"""Passwords, session tokens and the login throttle.

* Passwords are hashed with Argon2id (argon2-cffi), never stored or logged.
* A login gets a random 256-bit token (:func:`new_token`); the browser keeps
  it in an HttpOnly cookie, the database keeps only its SHA-256
  (:func:`hash_token`), so a leaked database cannot be replayed as cookies. A
  fast hash is right here: the token is random, not a guessable password.
* :class:`LoginThrottle` limits failed logins per user name and attempts per
  client address over a sliding window, and says how long to wait.
"""

from __future__ import annotations

import hashlib
import math
import re
import secrets
import threading
from collections import deque
from datetime import datetime, timedelta

from argon2 import PasswordHasher

from thermolab.errors import InvalidParameterError, ThermoLabError
from thermolab.lab.clock import LabClock

__all__ = [
    "AuthenticationError",
    "LoginThrottle",
    "RateLimitedError",
    "default_password_hasher",
    "hash_token",
    "new_token",
    "normalize_username",
    "validate_password",
]

_USERNAME = re.compile(r"^[a-z0-9][a-z0-9._@-]{0,63}$")
MIN_PASSWORD_LENGTH = 8
MAX_PASSWORD_LENGTH = 1024


class AuthenticationError(ThermoLabError):
    """No valid session, or a wrong user name or password (HTTP 401)."""


class RateLimitedError(ThermoLabError):
    """Too many login attempts; ``retry_after`` says how many seconds to wait (HTTP 429)."""

    def __init__(self, message: str, retry_after: float) -> None:
        super().__init__(message)
        self.retry_after = retry_after


def default_password_hasher() -> PasswordHasher:
    """Return the Argon2id hasher with argon2-cffi's recommended parameters.

    Examples
    --------
    >>> hasher = default_password_hasher()
    >>> hasher.verify(hasher.hash("correct horse"), "correct horse")
    True
    """
    return PasswordHasher()


def new_token() -> str:
    """Return a new random session token (43 URL-safe characters, 256 bits).

    Examples
    --------
    >>> len(new_token())
    43
    """
    return secrets.token_urlsafe(32)


def hash_token(token: str) -> str:
    """Return the SHA-256 (hex) under which a session token is stored.

    Examples
    --------
    >>> hash_token("abc")[:16]
    'ba7816bf8f01cfea'
    """
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


def normalize_username(username: str) -> str:
    """Return a user name in its stored form (trimmed, lower case), checking it.

    Raises
    ------
    InvalidParameterError
        If it is empty, too long or has characters other than letters, digits
        and ``. _ @ -``.

    Examples
    --------
    >>> normalize_username(" Alice ")
    'alice'
    """
    name = username.strip().lower()
    if not _USERNAME.match(name):
        raise InvalidParameterError(
            f"user name {username!r} is not valid: use 1 to 64 letters, digits, '.', '_', "
            "'@' or '-', starting with a letter or digit"
        )
    return name


def validate_password(password: str) -> str:
    """Check a new password's length and return it unchanged.

    Raises
    ------
    InvalidParameterError
        If it is shorter than 8 or longer than 1024 characters.

    Examples
    --------
    >>> validate_password("long enough")
    'long enough'
    """
    if len(password) < MIN_PASSWORD_LENGTH:
        raise InvalidParameterError(
            f"password too short: at least {MIN_PASSWORD_LENGTH} characters are needed"
        )
    if len(password) > MAX_PASSWORD_LENGTH:
        raise InvalidParameterError(
            f"password too long: at most {MAX_PASSWORD_LENGTH} characters are allowed"
        )
    return password


class LoginThrottle:
    """Sliding-window limits on login attempts.

    Two limits, both over ``window`` seconds: failed logins per user name
    (guessing one account's password), and attempts of any outcome per client
    address (trying many accounts). A success clears the user name's failures.

    Parameters
    ----------
    clock : LabClock
        Source of time.
    failures_per_user : int
        Failed logins allowed per user name within the window.
    attempts_per_address : int
        Attempts allowed per client address within the window.
    window : float
        Seconds.

    Notes
    -----
    The counts live in memory: they protect one server process, and a restart
    forgets them (a restart is far slower than the window anyway).

    Examples
    --------
    >>> from thermolab.lab.clock import ManualClock
    >>> clock = ManualClock()
    >>> throttle = LoginThrottle(clock, failures_per_user=2, attempts_per_address=10, window=60)
    >>> for _ in range(2):
    ...     throttle.check("alice", "10.0.0.1")
    ...     throttle.record("alice", "10.0.0.1", success=False)
    >>> throttle.check("alice", "10.0.0.1")
    Traceback (most recent call last):
    ...
    thermolab.lab.security.RateLimitedError: too many failed logins for 'alice'; try again in 60 s
    >>> clock.advance(60)
    >>> throttle.check("alice", "10.0.0.1")
    """

    def __init__(
        self,
        clock: LabClock,
        *,
        failures_per_user: int = 5,
        attempts_per_address: int = 30,
        window: float = 60.0,
    ) -> None:
        self._clock = clock
        self._per_user = failures_per_user
        self._per_address = attempts_per_address
        self._window = timedelta(seconds=window)
        self._failures: dict[str, deque[datetime]] = {}
        self._attempts: dict[str, deque[datetime]] = {}
        self._lock = threading.Lock()

    def check(self, username: str, address: str) -> None:
        """Raise if a login for ``username`` from ``address`` must wait.

        Raises
        ------
        RateLimitedError
            With ``retry_after`` in seconds.
        """
        now = self._clock.now()
        with self._lock:
            wait = self._wait(self._attempts, address, self._per_address, now)
            if wait is not None:
                raise RateLimitedError(
                    f"too many login attempts from {address}; try again in {_seconds(wait)} s",
                    wait,
                )
            wait = self._wait(self._failures, username, self._per_user, now)
            if wait is not None:
                raise RateLimitedError(
                    f"too many failed logins for {username!r}; try again in {_seconds(wait)} s",
                    wait,
                )

    def record(self, username: str, address: str, *, success: bool) -> None:
        """Count one login attempt and its outcome."""
        now = self._clock.now()
        with self._lock:
            self._attempts.setdefault(address, deque()).append(now)
            if success:
                self._failures.pop(username, None)
            else:
                self._failures.setdefault(username, deque()).append(now)
            if len(self._attempts) + len(self._failures) > 10_000:
                self._forget_old(now)

    def _wait(
        self, table: dict[str, deque[datetime]], key: str, limit: int, now: datetime
    ) -> float | None:
        times = table.get(key)
        if times is None:
            return None
        while times and now - times[0] >= self._window:
            times.popleft()
        if not times:
            del table[key]
            return None
        if len(times) < limit:
            return None
        return (times[0] + self._window - now).total_seconds()

    def _forget_old(self, now: datetime) -> None:
        # Bound the memory an attacker can make us use with made-up names.
        for table in (self._attempts, self._failures):
            for key in [k for k, v in table.items() if not v or now - v[-1] >= self._window]:
                del table[key]


def _seconds(wait: float) -> int:
    return max(1, math.ceil(wait))
