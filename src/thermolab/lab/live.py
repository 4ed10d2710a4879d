"""The live stream of each rig (WebSocket ``/api/rigs/{rig}/live``, ``docs/live-protocol.md``).

Every rig has a :class:`LiveChannel`. Publishers — a run's sampling thread,
the lab's sweep, a request that changed who controls the rig — call
:meth:`LiveChannel.publish` from any thread; it numbers the message (``seq``),
keeps it in a ring for clients that reconnect, encodes it to JSON **once**, and
hands the text to the event loop, which appends it to each client's bounded
queue. Nothing a client does can delay a publisher or the other clients: a
client whose queue is full is cut (closed with 4408) and may reconnect with
``since``. Access messages differ per client (each sees its own queue place);
they are rendered from one snapshot of the rig, at most a few times a second.

``seq`` starts, for each rig, from the wall clock at start-up in
microseconds and grows by one per message, so it grows across server
restarts too (a client that reconnects after a restart never sees an older
number) and stays an exact integer in a browser (below 2**53).
"""

from __future__ import annotations

import asyncio
import json
import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

__all__ = ["CLOSE_TOO_SLOW", "LiveChannel", "LiveClient", "LiveHub", "encode"]

log = logging.getLogger(__name__)

CLOSE_UNAUTHORIZED = 4401
CLOSE_UNKNOWN_RIG = 4404
CLOSE_TOO_SLOW = 4408
CLOSE_TOO_BIG = 1009
MAX_CLIENT_MESSAGE = 4096

REPLAYED = frozenset({"sample", "estimate", "run"})


def encode(message: dict[str, Any]) -> str:
    """Return ``message`` as compact JSON, non-finite numbers as ``null``.

    Examples
    --------
    >>> encode({"type": "sample", "y": float("nan")})
    '{"type":"sample","y":null}'
    """
    return json.dumps(_finite(message), separators=(",", ":"), allow_nan=False)


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


@dataclass(eq=False)
class LiveClient:
    """One connected client: its bounded queue of encoded messages (loop thread only).

    Attributes
    ----------
    key : object
        Whom the client is (the channel's ``render_access`` receives it).
    maxsize : int
        Messages queued before the client counts as too slow.
    """

    key: Any
    maxsize: int = 2000
    queue: deque[str] = field(default_factory=deque)
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    cut: bool = False
    sent: int = 0
    last_ping: datetime | None = None

    def offer(self, text: str) -> None:
        """Queue ``text``, or cut the client if its queue is full."""
        if self.cut:
            return
        if len(self.queue) >= self.maxsize:
            self.cut = True
            self.queue.clear()
        else:
            self.queue.append(text)
        self.wake.set()


class LiveChannel:
    """The live stream of one rig.

    Parameters
    ----------
    rig_id : str
    ring : int
        Replayable messages kept for reconnecting clients.
    seq_base : int, optional
        First ``seq`` (default: microseconds since the epoch, now).

    Examples
    --------
    >>> channel = LiveChannel("twin", ring=3, seq_base=100)
    >>> for k in range(5):
    ...     _ = channel.publish({"type": "sample", "run": 1, "k": k, "t": k, "u": 0, "y": 0})
    >>> channel.seq, [m["k"] for m in channel.replay_since(101)[0]]
    (105, [2, 3, 4])
    >>> channel.replay_since(100)[1]  # seq 101 has left the ring: the caller fills the gap
    True
    """

    def __init__(self, rig_id: str, *, ring: int = 4096, seq_base: int | None = None) -> None:
        self.rig_id = rig_id
        self.seq = seq_base if seq_base is not None else time.time_ns() // 1000
        self._ring: deque[tuple[int, dict[str, Any]]] = deque(maxlen=ring)
        self._clients: set[LiveClient] = set()
        self._lock = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self.render_access: Callable[[list[LiveClient]], None] | None = None

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Deliver to clients on ``loop`` (``None``: no clients, messages only numbered)."""
        self._loop = loop

    def publish(self, message: dict[str, Any]) -> int | None:
        """Send ``message`` to every client; return its ``seq`` if it is replayable.

        Thread-safe and never blocks on a client.
        """
        replayable = message.get("type") in REPLAYED
        with self._lock:
            seq = None
            if replayable:
                self.seq += 1
                seq = self.seq
                message = {**message, "seq": seq}
                self._ring.append((seq, message))
            text = encode(message)
        self._deliver(lambda: self._fan_out(text))
        return seq

    def attach(self, client: LiveClient) -> int:
        """Add a client; return the ``seq`` it starts after (call in the loop thread).

        Messages published after this call reach the client's queue; those
        up to the returned number are for :meth:`replay_since`.
        """
        with self._lock:
            self._clients.add(client)
            return self.seq

    def detach(self, client: LiveClient) -> None:
        """Remove a client."""
        with self._lock:
            self._clients.discard(client)

    def clients(self) -> list[LiveClient]:
        """The connected clients."""
        with self._lock:
            return list(self._clients)

    def replay_since(
        self, since: int, upto: int | None = None
    ) -> tuple[list[dict[str, Any]], bool]:
        """Return the kept messages with ``since < seq <= upto`` and whether some are missing.

        The flag is true when messages after ``since`` have already left the
        ring (the caller fills the gap from the store).
        """
        upto = self.seq if upto is None else upto
        with self._lock:
            kept = [m for s, m in self._ring if since < s <= upto]
            oldest = self._ring[0][0] if self._ring else self.seq + 1
        gap = since + 1 < oldest and since < upto
        return kept, gap

    def send_each(self, render: Callable[[LiveClient], dict[str, Any] | None]) -> None:
        """Send each client its own message (``render`` runs in the loop thread)."""

        def run() -> None:
            for client in self.clients():
                message = render(client)
                if message is not None:
                    client.offer(encode(message))

        self._deliver(run)

    def _deliver(self, action: Callable[[], None]) -> None:
        loop = self._loop
        if loop is None or loop.is_closed():
            return
        try:
            running = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if running is loop:
            action()
        else:
            loop.call_soon_threadsafe(action)

    def _fan_out(self, text: str) -> None:
        for client in self.clients():
            client.offer(text)


class LiveHub:
    """The live channels of every rig of a lab.

    Parameters
    ----------
    rig_ids : iterable of str
    """

    def __init__(self, rig_ids: list[str]) -> None:
        self.channels = {rig_id: LiveChannel(rig_id) for rig_id in rig_ids}
        self._access_pending: set[str] = set()
        self._lock = threading.Lock()
        self.loop: asyncio.AbstractEventLoop | None = None

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Deliver on ``loop`` (the server's event loop)."""
        self.loop = loop
        for channel in self.channels.values():
            channel.bind(loop)

    def publish(self, rig_id: str, message: dict[str, Any]) -> None:
        """Publish on a rig's channel (unknown rigs are ignored)."""
        channel = self.channels.get(rig_id)
        if channel is not None:
            channel.publish(message)

    def access_changed(self, rig_id: str, refresh: Callable[[str], None], delay: float) -> None:
        """Ask for ``refresh(rig_id)`` soon, once however many changes come meanwhile."""
        loop = self.loop
        if loop is None or loop.is_closed():
            return
        with self._lock:
            if rig_id in self._access_pending:
                return
            self._access_pending.add(rig_id)

        def fire() -> None:
            with self._lock:
                self._access_pending.discard(rig_id)
            refresh(rig_id)

        loop.call_soon_threadsafe(loop.call_later, delay, fire)
