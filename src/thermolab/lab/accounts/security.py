"""Passwords, session tokens and the login throttle.

* Passwords are hashed with Argon2id (argon2-cffi), never stored or logged.
* A login gets a random 256-bit token (:func:`new_token`); the browser keeps
  it in an HttpOnly cookie, the database keeps only its SHA-256
  (:func:`hash_token`), so a leaked database cannot be replayed as cookies. A
  fast hash is right here: the token is random, not a guessable password.
* A new password (:func:`validate_password`) has 12 to 1024 characters, is not
  blank, is not the user name or a variant of it, and is not one of the
  30 000 most common breached passwords. That list is the ``passwords``
  frequency list shipped by the zxcvbn package (offline, from real breaches;
  zxcvbn is a well-kept port of Dropbox's estimator, and we only use its
  list, not its score, which would refuse long passphrases ASVS allows), and
  is not guessable in under a million tries by zxcvbn's estimate (keyboard
  rows, sequences, repeats, dates, the lab's own name: ``123456789012``,
  ``qwertyuiopas``, ``aaaaaaaaaaaa``, ``thermolab123``).
* :class:`LoginThrottle` delays failed logins per (user name, client address)
  with a doubling, capped delay (never a lock-out: the right password from the
  teacher's own machine is never refused because someone else guessed), and
  limits attempts per client address over a sliding window.
"""

from __future__ import annotations

import hashlib
import math
import re
import secrets
import threading
from collections import deque
from datetime import datetime, timedelta
from functools import cache

from argon2 import PasswordHasher

from thermolab.errors import PasswordRejectedError, ThermoLabError
from thermolab.lab.accounts.names import normalize_username
from thermolab.lab.clock import LabClock

__all__ = [
    "AuthenticationError",
    "LoginThrottle",
    "RateLimitedError",
    "address_limited",
    "default_password_hasher",
    "hash_token",
    "new_token",
    "normalize_username",
    "pair_delayed",
    "validate_password",
]

MIN_PASSWORD_LENGTH = 12
MAX_PASSWORD_LENGTH = 1024
# Characters people put around a name to make a "new" password of it.
_DECORATION = re.compile(r"[\s\d!@#$%^&*()_+=.,;:'\"?<>/\\|`~\[\]{}-]+")


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


def validate_password(password: str, username: str | None = None) -> str:
    """Check a new password (OWASP ASVS 4.0 level 1, V2.1) and return it unchanged.

    Parameters
    ----------
    password : str
    username : str, optional
        The account's name: the password may not be it or a variant of it.

    Raises
    ------
    PasswordRejectedError (an InvalidParameterError)
        If it has fewer than 12 or more than 1024 characters, is only
        whitespace, is the user name (in any case, reversed, or with digits
        and punctuation around it), or is a commonly breached password. The
        message never repeats the password.

    Examples
    --------
    >>> validate_password("long enough phrase")
    'long enough phrase'
    >>> validate_password("password1234")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    thermolab.errors.PasswordRejectedError: this password is in a list of breached ...
    >>> validate_password("Alice.Smith2024!", "alice.smith")
    Traceback (most recent call last):
    ...
    thermolab.errors.PasswordRejectedError: the password may not be the user name or a variant of it
    """
    if len(password) < MIN_PASSWORD_LENGTH:
        raise PasswordRejectedError("password.too_short", limit=MIN_PASSWORD_LENGTH)
    if len(password) > MAX_PASSWORD_LENGTH:
        raise PasswordRejectedError("password.too_long", limit=MAX_PASSWORD_LENGTH)
    if not password.strip():
        raise PasswordRejectedError("password.blank")
    if username is not None and _is_name_variant(password, username):
        raise PasswordRejectedError("password.user_name")
    if _is_breached(password):
        raise PasswordRejectedError("password.breached")
    if _is_guessable(password, username):
        raise PasswordRejectedError("password.guessable")
    return password


# Fewer estimated guesses than this (zxcvbn's score 0 or 1) is guessable online.
_MIN_GUESSES_LOG10 = 6.0
_ZXCVBN_CHARS = 100  # zxcvbn's cost grows with the length; its authors cap the input too
_OWN_WORDS = ("thermolab", "thermo", "lab", "tclab")


def _is_guessable(password: str, username: str | None) -> bool:
    from zxcvbn import zxcvbn

    words = [*_OWN_WORDS, *([username] if username else [])]
    estimate = zxcvbn(password[:_ZXCVBN_CHARS], user_inputs=words)
    return float(estimate["guesses_log10"]) < _MIN_GUESSES_LOG10


def _core(text: str) -> str:
    return _DECORATION.sub("", text.casefold())


def _is_name_variant(password: str, username: str) -> bool:
    name = _core(username)
    core = _core(password)
    if not name:
        return False
    # The name itself, reversed, repeated, or merely decorated with digits and punctuation.
    return core in (name, name[::-1]) or _repeated_unit(core) == [name]


@cache
def _breached() -> frozenset[str]:
    from zxcvbn.frequency_lists import FREQUENCY_LISTS

    return frozenset(FREQUENCY_LISTS["passwords"])


_AFFIXES = re.compile(r"^[\d\W_]*(.*?)[\d\W_]*$", re.DOTALL)


def _is_breached(password: str) -> bool:
    folded = password.casefold()
    # The list holds lower-case passwords; people meet length rules by adding digits or
    # punctuation around one ("password1234", "!!dragon2024") or by repeating it, so the
    # bare word counts too.
    stem = _AFFIXES.sub(r"\1", folded)
    return any(
        candidate in _breached() for candidate in {folded, stem, *_repeated_unit(stem)} if candidate
    )


def _repeated_unit(text: str) -> list[str]:
    for size in range(1, len(text) // 2 + 1):
        if len(text) % size == 0 and text == text[:size] * (len(text) // size):
            return [text[:size]]
    return []


class LoginThrottle:
    """Delays on failed logins, and a limit on attempts per client address.

    Failed logins are counted per (user name, client address). The first
    ``failures_per_user`` are free; each further one doubles the wait before
    the next attempt of that pair (1 s, 2 s, 4 s, ...), capped at ``window``
    seconds. Nothing ever locks an account: someone guessing a teacher's
    password from another address does not delay the teacher at all, and even
    from the same address the right password is accepted once the (bounded)
    delay has passed. The count is forgotten 15 minutes after the last
    failure, and at once after a success. Attempts of any outcome per client
    address are also limited over a sliding ``window`` (trying many accounts).

    Parameters
    ----------
    clock : LabClock
        Source of time.
    failures_per_user : int
        Failed logins of one (user name, address) pair before delays start.
    attempts_per_address : int
        Attempts allowed per client address within the window.
    window : float
        Seconds: the sliding window of the address limit and the longest delay.

    Attributes
    ----------
    clock, failures_per_user, attempts_per_address
        As given (a shared throttle is built alike: ``SharedLoginThrottle.like``).
    window : timedelta

    Notes
    -----
    These counts live in memory: they protect one server process, and a restart
    forgets them (a restart is far slower than the delays anyway). Several web
    workers on one broker share theirs in Redis instead
    (:class:`~thermolab.lab.fleet.shared_limits.SharedLoginThrottle`, same rules).

    Examples
    --------
    >>> from thermolab.lab.clock import ManualClock
    >>> clock = ManualClock()
    >>> throttle = LoginThrottle(clock, failures_per_user=2, attempts_per_address=10, window=60)
    >>> for _ in range(3):
    ...     throttle.check("alice", "10.0.0.1")
    ...     throttle.record("alice", "10.0.0.1", success=False)
    >>> throttle.check("alice", "10.0.0.1")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    thermolab.lab.accounts.security.RateLimitedError: too many failed logins for 'alice' ...
    >>> throttle.check("alice", "10.0.0.2")  # another address is not delayed
    >>> clock.advance(1)
    >>> throttle.check("alice", "10.0.0.1")
    """

    FORGET = timedelta(minutes=15)
    """A pair's failures are forgotten this long after its last one."""

    def __init__(
        self,
        clock: LabClock,
        *,
        failures_per_user: int = 5,
        attempts_per_address: int = 30,
        window: float = 60.0,
    ) -> None:
        self.clock = clock
        self.failures_per_user = failures_per_user
        self.attempts_per_address = attempts_per_address
        self.window = timedelta(seconds=window)
        self._failures: dict[tuple[str, str], tuple[int, datetime]] = {}
        self._attempts: dict[str, deque[datetime]] = {}
        self._lock = threading.Lock()

    def delay(self, failures: int) -> float:
        """Seconds to wait after ``failures`` consecutive failures of one pair.

        Examples
        --------
        >>> from thermolab.lab.clock import ManualClock
        >>> t = LoginThrottle(ManualClock(), failures_per_user=5, window=60)
        >>> [t.delay(n) for n in (5, 6, 7, 8, 20)]
        [0.0, 1.0, 2.0, 4.0, 60.0]
        """
        extra = failures - self.failures_per_user
        if extra <= 0:
            return 0.0
        return min(2.0 ** min(extra - 1, 32), self.window.total_seconds())

    def check(self, username: str, address: str) -> None:
        """Raise if a login for ``username`` from ``address`` must wait.

        Raises
        ------
        RateLimitedError
            With ``retry_after`` in seconds.
        """
        now = self.clock.now()
        with self._lock:
            wait = self._address_wait(address, now)
            if wait is not None:
                raise address_limited(address, wait)
            failed = self._failures.get((username, address))
            if failed is None:
                return
            count, last = failed
            if now - last >= self.FORGET:
                del self._failures[(username, address)]
                return
            wait = self.delay(count) - (now - last).total_seconds()
            if wait > 0:
                raise pair_delayed(username, address, wait)

    def record(self, username: str, address: str, *, success: bool) -> None:
        """Count one login attempt and its outcome."""
        now = self.clock.now()
        key = (username, address)
        with self._lock:
            self._attempts.setdefault(address, deque()).append(now)
            if success:
                self._failures.pop(key, None)
            else:
                count, last = self._failures.get(key, (0, now))
                self._failures[key] = (0 if now - last >= self.FORGET else count) + 1, now
            if len(self._attempts) + len(self._failures) > 10_000:
                self._forget_old(now)

    def _address_wait(self, address: str, now: datetime) -> float | None:
        times = self._attempts.get(address)
        if times is None:
            return None
        while times and now - times[0] >= self.window:
            times.popleft()
        if not times:
            del self._attempts[address]
            return None
        if len(times) < self.attempts_per_address:
            return None
        return (times[0] + self.window - now).total_seconds()

    def _forget_old(self, now: datetime) -> None:
        # Bound the memory an attacker can make us use with made-up names.
        for address in [
            a for a, v in self._attempts.items() if not v or now - v[-1] >= self.window
        ]:
            del self._attempts[address]
        for key in [k for k, (_, last) in self._failures.items() if now - last >= self.FORGET]:
            del self._failures[key]


def address_limited(address: str, wait: float) -> RateLimitedError:
    """The refusal of a client address over its attempts for ``wait`` more seconds."""
    return RateLimitedError(
        f"too many login attempts from {address}; try again in {_seconds(wait)} s", wait
    )


def pair_delayed(username: str, address: str, wait: float) -> RateLimitedError:
    """The refusal of a (user name, address) pair delayed ``wait`` more seconds."""
    return RateLimitedError(
        f"too many failed logins for {username!r} from {address}; try again in {_seconds(wait)} s",
        wait,
    )


def _seconds(wait: float) -> int:
    return max(1, math.ceil(wait))
