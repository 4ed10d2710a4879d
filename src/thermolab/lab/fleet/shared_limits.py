"""The login throttles and the live-socket limits, lab-wide when workers share a Redis broker.

One ``thermolab serve`` process keeps them in memory
(:class:`~thermolab.lab.accounts.security.LoginThrottle`,
:class:`~thermolab.lab.lti.launch.InitiationRate`, :class:`LiveSocketCounts`).
Several workers on one broker (``--broker redis://...``, ``docs/fleet.md``)
would multiply them by the number of workers, so there they count in Redis:

* :class:`SharedLoginThrottle` keeps each client address's attempts (a sorted
  set of times) and each (user name, address) pair's failures (a hash) in
  Redis, read in one transaction and changed by one Lua script, with the
  rules and numbers of the in-memory throttle, which it extends. While Redis
  cannot be reached it falls back to this worker's own counts (it keeps them
  too): neither every student locked out nor unlimited guessing, only the
  per-worker limits of a lone server, for as long as the broker is away.
* :class:`SharedInitiationRate` counts each address's LTI login initiations
  in a sorted set, checked and added to by one Lua script, with the same
  fallback to this worker's count.
* :class:`SharedLiveSocketCounts` publishes this worker's live sockets per
  login and per rig as one Redis hash that expires unless refreshed (a dead
  worker's sockets stop counting within ``ttl`` seconds); admission adds the
  other live workers' published counts to this worker's exact ones.
"""

from __future__ import annotations

import collections
import hashlib
import secrets
import threading
from typing import Any

from thermolab.lab.accounts.security import LoginThrottle, address_limited, pair_delayed
from thermolab.lab.clock import LabClock
from thermolab.lab.fleet.worker_hashes import Reachable, WorkerHash
from thermolab.lab.lti.launch import InitiationRate

__all__ = [
    "LiveSocketCounts",
    "SharedInitiationRate",
    "SharedLiveSocketCounts",
    "SharedLoginThrottle",
]

# One attempt: its time in the address's window (trimmed to the newest ``keep``: the
# limit is reached with them, and they say when it is no longer), and, for a failure,
# the pair's count (started again when the last failure is forgotten).
_RECORD = """
local now = tonumber(ARGV[1])
redis.call('ZADD', KEYS[1], ARGV[1], ARGV[2])
redis.call('ZREMRANGEBYSCORE', KEYS[1], '-inf', ARGV[3])
redis.call('ZREMRANGEBYRANK', KEYS[1], 0, -(tonumber(ARGV[4]) + 1))
redis.call('EXPIRE', KEYS[1], ARGV[5])
if ARGV[6] == '1' then
  redis.call('DEL', KEYS[2])
  return 0
end
local count = 0
local old = redis.call('HMGET', KEYS[2], 'count', 'last')
if old[1] and now - tonumber(old[2]) < tonumber(ARGV[7]) then
  count = tonumber(old[1])
end
count = count + 1
redis.call('HSET', KEYS[2], 'count', count, 'last', ARGV[1])
redis.call('EXPIRE', KEYS[2], ARGV[8])
return count
"""


class SharedLoginThrottle(LoginThrottle):
    """:class:`~thermolab.lab.accounts.security.LoginThrottle` with its counts in Redis, lab-wide.

    Same rules, numbers and refusals; the times are the lab clock's (workers'
    clocks agree through NTP), Redis's expiries only forget keys no rule needs
    any more.

    Parameters
    ----------
    redis : redis.Redis
        The broker (:func:`figures_client`).
    prefix : str
        Put before every key: the lab's (its workers share it, another lab's differ).
    clock, failures_per_user, attempts_per_address, window
        As :class:`~thermolab.lab.accounts.security.LoginThrottle`'s.
    """

    def __init__(
        self,
        redis: Any,
        prefix: str,
        clock: LabClock,
        *,
        failures_per_user: int = 5,
        attempts_per_address: int = 30,
        window: float = 60.0,
    ) -> None:
        super().__init__(
            clock,
            failures_per_user=failures_per_user,
            attempts_per_address=attempts_per_address,
            window=window,
        )
        self._redis = redis
        self._prefix = prefix
        self._record_script = redis.register_script(_RECORD)
        self._reachable = Reachable("the login throttle")

    @classmethod
    def like(cls, throttle: LoginThrottle, redis: Any, prefix: str) -> SharedLoginThrottle:
        """A shared throttle with ``throttle``'s clock and numbers."""
        return cls(
            redis,
            prefix,
            throttle.clock,
            failures_per_user=throttle.failures_per_user,
            attempts_per_address=throttle.attempts_per_address,
            window=throttle.window.total_seconds(),
        )

    def check(self, username: str, address: str) -> None:
        """Raise if a login for ``username`` from ``address`` must wait (any worker's counts)."""
        if not self._reachable.now():
            return super().check(username, address)
        now = self.clock.now().timestamp()
        window = self.window.total_seconds()
        attempts, failures = self._keys(username, address)
        try:
            pipe = self._redis.pipeline(transaction=True)
            pipe.zremrangebyscore(attempts, "-inf", repr(now - window))
            pipe.zcard(attempts)
            pipe.zrange(attempts, 0, 0, withscores=True)
            pipe.hmget(failures, "count", "last")
            _, count, oldest, (failed, last) = pipe.execute()
        except Exception as exc:  # redis.RedisError, OSError: the broker is away
            self._reachable.failed(exc)
            return super().check(username, address)
        self._reachable.ok()
        if count >= self.attempts_per_address and oldest:
            raise address_limited(address, oldest[0][1] + window - now)
        if failed is None or last is None:
            return None
        since = now - float(last)
        if since >= self.FORGET.total_seconds():
            return None
        wait = self.delay(int(failed)) - since
        if wait > 0:
            raise pair_delayed(username, address, wait)
        return None

    def record(self, username: str, address: str, *, success: bool) -> None:
        """Count one login attempt and its outcome, here and in Redis."""
        # This worker's own counts too: they decide while Redis is unreachable.
        super().record(username, address, success=success)
        if not self._reachable.now():
            return
        now = self.clock.now().timestamp()
        window = self.window.total_seconds()
        forget = self.FORGET.total_seconds()
        try:
            self._record_script(
                keys=list(self._keys(username, address)),
                args=[
                    repr(now),
                    f"{now!r}:{secrets.token_hex(4)}",  # one member per attempt
                    repr(now - window),
                    self.attempts_per_address,
                    int(window) + 1,
                    "1" if success else "0",
                    repr(forget),
                    int(forget) + 1,
                ],
            )
        except Exception as exc:  # as in check
            self._reachable.failed(exc)
        else:
            self._reachable.ok()

    def _keys(self, username: str, address: str) -> tuple[str, str]:
        pair = hashlib.sha256(f"{username}\0{address}".encode()).hexdigest()[:32]
        return f"{self._prefix}login.address:{address}", f"{self._prefix}login.pair:{pair}"


# One LTI login initiation: the address's window trimmed, refused (0) at the limit,
# else counted (1). One script, so two workers cannot both take the last place.
_INITIATE = """
redis.call('ZREMRANGEBYSCORE', KEYS[1], '-inf', ARGV[3])
if redis.call('ZCARD', KEYS[1]) >= tonumber(ARGV[4]) then
  return 0
end
redis.call('ZADD', KEYS[1], ARGV[1], ARGV[2])
redis.call('EXPIRE', KEYS[1], ARGV[5])
return 1
"""


class SharedInitiationRate(InitiationRate):
    """:class:`~thermolab.lab.lti.launch.InitiationRate` counted in Redis, lab-wide.

    Parameters
    ----------
    redis : redis.Redis
        The broker (:func:`figures_client`).
    prefix : str
        The lab's key prefix.
    clock, per_address, window
        As :class:`~thermolab.lab.lti.launch.InitiationRate`'s.
    """

    def __init__(self, redis: Any, prefix: str, clock: LabClock, **numbers: Any) -> None:
        super().__init__(clock, **numbers)
        self._prefix = prefix
        self._script = redis.register_script(_INITIATE)
        self._reachable = Reachable("the LTI login throttle")

    @classmethod
    def like(cls, rate: InitiationRate, redis: Any, prefix: str) -> SharedInitiationRate:
        """A shared count with ``rate``'s clock and numbers."""
        return cls(redis, prefix, rate.clock, per_address=rate.per_address, window=rate.window)

    def check(self, address: str) -> None:
        """Count one initiation from ``address`` on every worker (this one's while Redis is away).

        Raises
        ------
        LtiThrottledError
            Past the limit.
        """
        if not self._reachable.now():
            return super().check(address)
        now = self.clock.now().timestamp()
        window = self.window.total_seconds()
        try:
            counted = self._script(
                keys=[f"{self._prefix}lti.login.address:{address}"],
                args=[
                    repr(now),
                    f"{now!r}:{secrets.token_hex(4)}",  # one member per initiation
                    repr(now - window),
                    self.per_address,
                    int(window) + 1,
                ],
            )
        except Exception as exc:  # redis.RedisError, OSError: the broker is away
            self._reachable.failed(exc)
            return super().check(address)
        self._reachable.ok()
        if not int(counted):
            raise self.refusal(address)
        # This worker's own count too (never past the lab-wide one): it decides while
        # Redis is unreachable.
        return super().check(address)


def _release(counts: collections.Counter[Any], key: Any) -> None:
    counts[key] -= 1
    if counts[key] <= 0:
        del counts[key]


def _login_field(login: tuple[str, int | None]) -> str:
    return f"l:{login[0]}:{login[1]}"


class LiveSocketCounts:
    """This worker's live sockets per login and per rig (exact; the event loop changes them).

    :meth:`others` is what other workers hold: nothing, for a lone server.
    """

    shared = False
    """``True`` when :meth:`others` asks other workers (it blocks: call it in a thread)."""

    def __init__(self) -> None:
        self._logins: collections.Counter[tuple[str, int | None]] = collections.Counter()
        self._rigs: collections.Counter[str] = collections.Counter()
        self._lock = threading.Lock()  # a publishing thread reads them

    def here(self, login: tuple[str, int | None], rig_id: str) -> tuple[int, int]:
        """This worker's sockets of ``login`` and on ``rig_id``."""
        return self._logins[login], self._rigs[rig_id]

    def others(self, login: tuple[str, int | None], rig_id: str) -> tuple[int, int]:
        """The other live workers' sockets of ``login`` and on ``rig_id``."""
        return 0, 0

    def add(self, login: tuple[str, int | None], rig_id: str) -> None:
        """One more socket."""
        with self._lock:
            self._logins[login] += 1
            self._rigs[rig_id] += 1
        self._changed()

    def remove(self, login: tuple[str, int | None], rig_id: str) -> None:
        """One socket fewer."""
        with self._lock:
            _release(self._logins, login)
            _release(self._rigs, rig_id)
        self._changed()

    def close(self) -> None:
        """Stop (nothing to stop here)."""

    def _changed(self) -> None:
        """A count changed (the shared counts publish it)."""

    def _fields(self) -> dict[str, int]:
        with self._lock:
            fields = {_login_field(login): n for login, n in self._logins.items()}
            fields.update({f"r:{rig}": n for rig, n in self._rigs.items()})
        return fields


class SharedLiveSocketCounts(LiveSocketCounts):
    """Live-socket counts published to Redis, and the other workers' read from it.

    This worker's counts are its :class:`~thermolab.lab.fleet.worker_hashes.WorkerHash`
    of kind ``live`` (one field per login and rig), written at once after each
    change and every ``refresh`` seconds, with a ``ttl``: a worker that dies
    stops counting ``ttl`` seconds after its last write.

    Parameters
    ----------
    redis : redis.Redis
        The broker (:func:`figures_client`).
    prefix : str
        The lab's key prefix.
    refresh, ttl : float
        Seconds between writes with no change, and a write's lifetime.
    """

    shared = True

    def __init__(self, redis: Any, prefix: str, *, refresh: float = 2.0, ttl: float = 6.0) -> None:
        super().__init__()
        self.published = WorkerHash(redis, prefix, "live", self._fields, refresh=refresh, ttl=ttl)

    def others(self, login: tuple[str, int | None], rig_id: str) -> tuple[int, int]:
        """The other live workers' published sockets of ``login`` and on ``rig_id``.

        Without Redis: nothing (this worker's own counts decide, as a lone server's).
        """
        found = self.published.others(_login_field(login), f"r:{rig_id}")
        if found is None:
            return 0, 0
        logins = sum(int(n) for n, _ in found if n is not None)
        rigs = sum(int(n) for _, n in found if n is not None)
        return logins, rigs

    def close(self) -> None:
        """Stop publishing and take this worker's counts out at once."""
        self.published.close()

    def _changed(self) -> None:
        self.published.changed()
