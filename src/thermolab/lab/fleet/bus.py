"""The message bus between a lab's web workers: the live stream and rig news, fanned out.

One ``thermolab serve`` process needs no bus: :class:`LocalBus` hands every
message to this process's own subscribers, in the publisher's thread. Several
workers on one database share one broker (``--broker redis://HOST:PORT/DB``):
:class:`RedisBus` publishes on Redis pub/sub channels and delivers what any
worker published, its own messages included, to this worker's subscribers.

Why Redis pub/sub (``docs/fleet.md``, "Measured", has the figures measured here
by ``benchmarks/bench_bus.py``): the live stream is fire-and-forget — a worker
that misses messages (it was restarting) fills the gap from the store by
sample index, like any reconnecting client — so a persistent log (JetStream,
Redis streams) buys nothing the store does not already give, while pub/sub
has the lowest delay and the least CPU per message of the buses measured.
The library (redis-py) does the protocol; this module only adds a sending
thread, so that a publisher (a run's sampling thread) never waits on the
network.

Topics are plain strings; payloads are bytes (JSON texts here).
"""

from __future__ import annotations

import logging
import queue
import threading
from collections import defaultdict
from collections.abc import Callable
from typing import Any, Protocol

from thermolab.errors import ConfigError

__all__ = ["Bus", "BusError", "LocalBus", "RedisBus", "open_bus"]

log = logging.getLogger(__name__)

Handler = Callable[[bytes], None]


class BusError(ConfigError):
    """The broker cannot be reached or the bus address is not understood."""


class Bus(Protocol):
    """Publish to topics and hear what anyone published on them."""

    shared: bool
    """``True`` when other processes hear this bus (a broker), ``False`` in process."""

    def publish(self, topic: str, data: bytes) -> None:
        """Send ``data`` to every subscriber of ``topic`` (any thread, never blocks long)."""

    def subscribe(self, topic: str, handler: Handler) -> None:
        """Call ``handler(data)`` for every message on ``topic`` (from the bus's thread)."""

    def close(self) -> None:
        """Stop delivering and let go of the broker."""

    def ping(self) -> None:
        """Return when the broker answers (``/readyz``); raise when it cannot be reached."""


class LocalBus:
    """The in-process bus: subscribers are called at once, in the publisher's thread.

    Examples
    --------
    >>> bus = LocalBus()
    >>> heard = []
    >>> bus.subscribe("news", heard.append)
    >>> bus.publish("news", b"hi")
    >>> heard
    [b'hi']
    """

    shared = False

    def __init__(self) -> None:
        self._handlers: defaultdict[str, list[Handler]] = defaultdict(list)

    def publish(self, topic: str, data: bytes) -> None:
        """Deliver ``data`` to ``topic``'s subscribers now."""
        for handler in list(self._handlers.get(topic, ())):
            handler(data)

    def subscribe(self, topic: str, handler: Handler) -> None:
        """Add a subscriber."""
        self._handlers[topic].append(handler)

    def close(self) -> None:
        """Forget every subscriber."""
        self._handlers.clear()

    def ping(self) -> None:
        """Nothing to reach: the bus is this process."""


_STOP = object()


class RedisBus:
    """Redis pub/sub: a sending thread and a listening thread (redis-py).

    Parameters
    ----------
    url : str
        ``redis://HOST:PORT/DB`` (``rediss://`` for TLS).
    prefix : str
        Put before every topic, so that several labs may share one Redis.
    """

    shared = True

    def __init__(self, url: str, *, prefix: str = "thermolab.") -> None:
        try:
            import redis
        except ImportError as exc:  # pragma: no cover - the optional dependency
            raise BusError(
                "a Redis broker needs redis-py: pip install 'thermolab[broker]'"
            ) from exc
        self._prefix = prefix
        try:
            self._redis: Any = redis.Redis.from_url(url, socket_connect_timeout=5)
            self._redis.ping()
        except (redis.RedisError, ValueError) as exc:
            raise BusError(f"cannot reach the broker at {url}: {exc}") from exc
        pubsub = self._redis.pubsub
        self._pubsub: Any = pubsub(ignore_subscribe_messages=True)  # type: ignore[no-untyped-call]
        self._handlers: defaultdict[str, list[Handler]] = defaultdict(list)
        self._outbox: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._closed = threading.Event()
        self._sender = threading.Thread(target=self._send_forever, name="bus-send", daemon=True)
        self._sender.start()
        self._listener: threading.Thread | None = None

    def publish(self, topic: str, data: bytes) -> None:
        """Queue ``data`` for ``topic``; the sending thread publishes it, in order."""
        if not self._closed.is_set():
            self._outbox.put((self._prefix + topic, data))

    def subscribe(self, topic: str, handler: Handler) -> None:
        """Listen to ``topic`` (the listening thread starts with the first subscription)."""
        with self._lock:
            self._handlers[self._prefix + topic].append(handler)
            self._pubsub.subscribe(self._prefix + topic)
            if self._listener is None:
                self._listener = threading.Thread(
                    target=self._listen_forever, name="bus-listen", daemon=True
                )
                self._listener.start()

    def ping(self) -> None:
        """One PING to the broker (raises redis-py's error when it does not answer)."""
        self._redis.ping()

    def close(self) -> None:
        """Stop both threads and close the connections."""
        if self._closed.is_set():
            return
        self._closed.set()
        self._outbox.put(_STOP)
        self._sender.join(timeout=5)
        try:
            self._pubsub.close()
            self._redis.close()
        except Exception:  # the broker may be gone already
            log.debug("closing the bus", exc_info=True)
        if self._listener is not None:
            self._listener.join(timeout=5)

    def _send_forever(self) -> None:
        while True:
            item = self._outbox.get()
            if item is _STOP:
                return
            # Whatever else is waiting goes in one round trip.
            pipe = self._redis.pipeline(transaction=False)
            while item is not None and item is not _STOP:
                pipe.publish(*item)
                try:
                    item = self._outbox.get_nowait()
                except queue.Empty:
                    item = None
            try:
                pipe.execute()
            except Exception:
                log.exception("the bus could not publish (the broker is unreachable?)")
            if item is _STOP:
                return

    def _listen_forever(self) -> None:
        while not self._closed.is_set():
            try:
                # redis-py's PubSub is not thread-safe: a subscription waits for this turn.
                with self._lock:
                    message = self._pubsub.get_message(timeout=0.2)
            except Exception:
                if self._closed.is_set():
                    return
                log.exception("the bus lost the broker; listening again")
                self._closed.wait(1.0)
                continue
            if message is None or message.get("type") != "message":
                continue
            channel = message["channel"]
            topic = channel.decode() if isinstance(channel, bytes) else str(channel)
            for handler in list(self._handlers.get(topic, ())):
                try:
                    handler(message["data"])
                except Exception:
                    log.exception("a bus subscriber failed on %s", topic)


def open_bus(url: str | None, *, prefix: str = "thermolab.") -> Bus:
    """The bus at ``url`` (``redis://...``), or the in-process bus for ``None``.

    ``prefix`` goes before every topic: one lab's workers share it, another
    lab on the same broker uses another.

    Raises
    ------
    BusError
        For an address of another kind, or a broker that cannot be reached.
    """
    if url is None:
        return LocalBus()
    if url.startswith(("redis://", "rediss://", "unix://")):
        return RedisBus(url, prefix=prefix)
    raise BusError(f"--broker {url}: use redis://HOST:PORT/DB (the bus ThermoLab supports)")
