"""What each web worker of a fleet publishes about itself in Redis, and reads of the others.

Several workers on one broker (``docs/fleet.md``) each keep some figures in
memory, exactly (their live sockets, who watches their rigs); the lab-wide
figure is this worker's own plus what the other live workers published.
:class:`WorkerHash` is that publication: one Redis hash per worker,
rewritten whole by a thread after each change and every ``refresh`` seconds,
expiring ``ttl`` seconds after its last write (a killed worker's figures stop
counting then; one that stops cleanly deletes its hash at once), and a set
naming the workers that published, which readers tidy.

:class:`Reachable` is how every shared figure behaves while Redis cannot be
reached: it stops asking for :data:`BACK_OFF` seconds, and this worker's own
figures decide meanwhile, as a lone server's would.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["BACK_OFF", "Reachable", "WorkerHash", "figures_client"]

log = logging.getLogger(__name__)

BACK_OFF = 5.0
"""Seconds during which, after Redis failed, this worker's own figures alone decide."""


def figures_client(url: str) -> Any:
    """A redis-py client for the shared figures (the limits, the watchers): short timeouts,
    so that a lost broker costs a login or a socket about a second, not a hang."""
    import redis

    return redis.Redis.from_url(url, socket_connect_timeout=1.0, socket_timeout=1.0)


class Reachable:
    """Whether to ask Redis now: not for :data:`BACK_OFF` seconds after it failed.

    Parameters
    ----------
    what : str
        What asks (for the log: "the login throttle").
    """

    def __init__(self, what: str) -> None:
        self._what = what
        self._failed_at: float | None = None

    def now(self) -> bool:
        """``True`` unless Redis failed less than :data:`BACK_OFF` seconds ago."""
        failed = self._failed_at
        return failed is None or time.monotonic() - failed >= BACK_OFF

    def failed(self, error: Exception) -> None:
        """Redis failed (logged once per outage)."""
        if self._failed_at is None:
            log.warning(
                "%s: Redis unreachable (%s); this worker's counts decide", self._what, error
            )
        self._failed_at = time.monotonic()

    def ok(self) -> None:
        """Redis answered."""
        if self._failed_at is not None:
            log.warning("%s: Redis reachable again; the counts are lab-wide", self._what)
        self._failed_at = None


Fields = Mapping[str, str | int]


class WorkerHash:
    """This worker's figures as a Redis hash that expires unless rewritten; the others' read.

    A publishing thread writes ``fields()`` (plus ``alive``) as the hash
    ``<prefix><kind>.worker:<id>`` at once after :meth:`changed` — at most
    once every ``gap`` seconds — and every ``refresh`` seconds, each write
    living ``ttl`` seconds. The set ``<prefix><kind>.workers`` names the
    workers; a reader drops the names whose hash has expired.

    Parameters
    ----------
    redis : redis.Redis
        The broker (:func:`~thermolab.lab.fleet.worker_hashes.figures_client`).
    prefix : str
        The lab's key prefix.
    kind : str
        What is published ("live", "watchers"): each kind has its own hashes.
    fields : callable
        This worker's figures now (called in the publishing thread).
    refresh, ttl : float
        Seconds between writes with no change, and a write's lifetime.
    gap : float
        Least seconds between two writes (changes in between are written together).
    """

    def __init__(
        self,
        redis: Any,
        prefix: str,
        kind: str,
        fields: Callable[[], Fields],
        *,
        refresh: float = 2.0,
        ttl: float = 6.0,
        gap: float = 0.0,
    ) -> None:
        self._redis = redis
        self._fields = fields
        self._workers = f"{prefix}{kind}.workers"
        self._key_prefix = f"{prefix}{kind}.worker:"
        self.worker = uuid.uuid4().hex
        self._key = self._key_prefix + self.worker
        self._refresh = refresh
        self._ttl_ms = int(ttl * 1000)
        self._gap = gap
        self.reachable = Reachable(f"the workers' {kind}")
        self._dirty = threading.Event()
        self._stop = threading.Event()
        self._dirty.set()  # the first write says this worker is alive
        self._publisher = threading.Thread(
            target=self._publish_forever, name=f"{kind}-publish", daemon=True
        )
        self._publisher.start()

    def changed(self) -> None:
        """This worker's figures changed: write them soon."""
        self._dirty.set()

    def others(self, *fields: str) -> list[list[bytes | None]] | None:
        """The other live workers' values of ``fields`` (``None``: Redis unreachable)."""
        found = self._read(lambda pipe, key: pipe.hmget(key, "alive", *fields))
        return None if found is None else [values[1:] for values in found]

    def others_whole(self) -> list[dict[bytes, bytes]] | None:
        """The other live workers' whole hashes (``None``: Redis unreachable)."""
        return self._read(lambda pipe, key: pipe.hgetall(key))

    def _read(self, ask: Callable[[Any, str], Any]) -> list[Any] | None:
        # One round trip for the names, one pipeline for their hashes; the names of
        # expired hashes are dropped from the set.
        if not self.reachable.now():
            return None
        try:
            names = (w.decode() for w in self._redis.smembers(self._workers))
            workers = [w for w in names if w != self.worker]
            pipe = self._redis.pipeline(transaction=False)
            for worker in workers:
                ask(pipe, self._key_prefix + worker)
            found = pipe.execute() if workers else []
            dead = [w for w, answer in zip(workers, found, strict=True) if not _alive(answer)]
            if dead:
                self._redis.srem(self._workers, *dead)
        except Exception as exc:  # redis.RedisError, OSError: the broker is away
            self.reachable.failed(exc)
            return None
        self.reachable.ok()
        return [answer for answer in found if _alive(answer)]

    def halt(self) -> None:
        """Stop writing, leaving the hash to expire (as a killed worker's would)."""
        self._stop.set()
        self._dirty.set()
        self._publisher.join(timeout=5)

    def close(self) -> None:
        """Stop writing and take this worker's hash out at once."""
        self.halt()
        try:
            pipe = self._redis.pipeline(transaction=True)
            pipe.delete(self._key)
            pipe.srem(self._workers, self.worker)
            pipe.execute()
        except Exception:  # the broker may be gone: the hash expires anyway
            log.debug("removing this worker's %s", self._key, exc_info=True)

    def _publish_forever(self) -> None:
        while not self._stop.is_set():
            self._dirty.wait(self._refresh)
            if self._stop.is_set():
                return
            self._dirty.clear()
            # The whole hash each time, as the figures are now: a lost write heals at the next.
            fields: dict[str, str | int] = {"alive": 1, **self._fields()}
            try:
                pipe = self._redis.pipeline(transaction=True)
                pipe.delete(self._key)
                pipe.hset(self._key, mapping=fields)
                pipe.pexpire(self._key, self._ttl_ms)
                pipe.sadd(self._workers, self.worker)
                pipe.pexpire(self._workers, self._ttl_ms)
                pipe.execute()
            except Exception as exc:  # the broker is away: try again at the next refresh
                self.reachable.failed(exc)
            if self._gap > 0:
                self._stop.wait(self._gap)  # changes meanwhile wait, and go together


def _alive(answer: Any) -> bool:
    # hmget's answer starts with "alive"; hgetall's is a dict, empty once expired.
    if isinstance(answer, dict):
        return b"alive" in answer
    return bool(answer) and answer[0] is not None
