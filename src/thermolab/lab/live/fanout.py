"""The live stream of each rig (WebSocket ``/api/rigs/{rig}/live``, ``docs/live-protocol.md``).

Every rig has a :class:`LiveChannel`. Publishers — a run's sampling thread,
the lab's sweep, a request that changed who controls the rig — call
:meth:`LiveChannel.publish` from any thread; it numbers the message (``seq``),
keeps it in a ring for clients that reconnect, encodes it to JSON **once**,
and appends the text to the channel's pending list. The event loop takes
whatever is pending in one go (a sample and its estimates, published a few
microseconds apart, travel together) and hands the same :class:`Batch` to
every client's bounded queue: no per-client encoding, and one WebSocket frame
per client for the whole batch. A client that is behind gets its whole
backlog in one frame too (a JSON array of the messages, in order).

Where the server offers it (``thermolab serve``: the ASGI scope extension
:data:`FRAMES_EXTENSION`, a :class:`FrameWriter`), a client that has caught
up is written to directly: the batch's WebSocket frame is built once
(:func:`text_frame`) and the same bytes go to every such client's socket —
no per-client task, ASGI call or frame encoding. Anywhere else (tests'
in-process clients, other ASGI servers) each client's send task takes its
queue through the ASGI ``send``.

Nothing a client does can delay a publisher or the other clients: a client
whose queue is full (or, written to directly, whose socket holds more than
its byte bound unsent) is cut (closed with 4408) and may reconnect with
``since``. Access messages differ per client (each sees its own queue
place); they are rendered from one snapshot of the rig, at most a few times
a second.

``seq`` starts, for each rig, from the wall clock at start-up in
microseconds and grows by one per message. A rig publishes far fewer than a
million messages a second, so the numbers a server gives stay below the wall
clock in microseconds; a server started later therefore starts above them
(unless the system clock was set back, across the restart, by more than the
server was down: clients then see ``hello.seq`` below their last number and
start again from it). The numbers stay exact integers in a browser (below
2**53 until the year 2255), and numbering needs no write to the store.
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from functools import cached_property
from typing import Any

from thermolab.jsonsafe import json_safe
from thermolab.lab.live.frames import FRAMES_EXTENSION, MAX_UNSENT_BYTES, FrameWriter, text_frame

__all__ = [
    "CLOSE_BAD_REQUEST",
    "CLOSE_TOO_SLOW",
    "CLOSE_UNAUTHORIZED",
    "FRAMES_EXTENSION",
    "MAX_FRAME_MESSAGES",
    "Batch",
    "FrameWriter",
    "LiveChannel",
    "LiveClient",
    "LiveFanout",
    "encode",
    "text_frame",
]

log = logging.getLogger(__name__)

CLOSE_BAD_REQUEST = 4400
CLOSE_UNAUTHORIZED = 4401
CLOSE_UNKNOWN_RIG = 4404
CLOSE_TOO_SLOW = 4408
CLOSE_TOO_BIG = 1009
CLOSE_TOO_MANY = 4429
"""The login holds its most live sockets (``access.live_sockets_per_login``)."""
CLOSE_RIG_FULL = 4503
"""The rig has its most live sockets (``access.live_sockets_per_rig``)."""
MAX_SEQ = 2**53
"""The largest ``seq`` (and ``since``) there is: numbers stay exact in a browser."""
MAX_CLIENT_MESSAGE = 4096
MAX_CLIENT_NESTING = 8
"""Client messages nest at most this deep (a ping nests 1); deeper ones get an ``error``."""
MAX_FRAME_MESSAGES = 1000
"""At most this many messages travel in one frame (a backlog goes in several)."""

REPLAYED = frozenset({"sample", "estimate", "run"})


def encode(message: Mapping[str, Any]) -> str:
    """Return ``message`` as compact JSON, non-finite numbers as ``null``.

    Examples
    --------
    >>> encode({"type": "sample", "y": float("nan")})
    '{"type":"sample","y":null}'
    """
    return json.dumps(json_safe(message), separators=(",", ":"), allow_nan=False)


@dataclass(frozen=True)
class Batch:
    """Encoded messages that travel together, shared by every client they go to.

    Attributes
    ----------
    body : str
        The messages' JSON texts joined by commas.
    count : int
        How many messages.
    frame : str
        What one frame carries: the message itself, or a JSON array of them.

    Examples
    --------
    >>> Batch.of(['{"a":1}']).frame
    '{"a":1}'
    >>> Batch.of(['{"a":1}', '{"b":2}']).frame
    '[{"a":1},{"b":2}]'
    """

    body: str
    count: int
    frame: str

    @cached_property
    def wire(self) -> bytes:
        """The frame as the socket carries it (built once, whatever the clients)."""
        return text_frame(self.frame.encode())

    @classmethod
    def of(cls, texts: list[str]) -> Batch:
        """Join encoded messages (at least one) into a batch."""
        body = ",".join(texts)
        return cls(body, len(texts), body if len(texts) == 1 else f"[{body}]")


@dataclass(eq=False)
class LiveClient:
    """One connected client: its bounded queue of message batches (loop thread only).

    Attributes
    ----------
    key : object
        Whom the client is (the channel's ``render_access`` receives it).
    maxsize : int
        Messages queued before the client counts as too slow.
    queued : int
        Messages waiting in the queue.
    wake : asyncio.Event
        Set when there is something to send (or the connection is to end).
    ended : asyncio.Event
        Set when the server ends the connection.
    closing : tuple of (int, str) or None
        Why the server ends the connection (close code, reason), once it does.
    sent : int
        Frames sent so far.
    direct : FrameWriter or None
        Set once the client has caught up, where the server offers direct
        writes: batches then go straight to its socket.

    Examples
    --------
    >>> client = LiveClient("ana", maxsize=3)
    >>> client.offer_batch(Batch.of(['{"k":0}', '{"k":1}']))
    >>> client.offer('{"k":2}')
    >>> client.next_frame(), client.next_frame()
    ('[{"k":0},{"k":1},{"k":2}]', None)
    >>> client.offer_batch(Batch.of(['{"k":3}', '{"k":4}', '{"k":5}', '{"k":6}']))
    >>> client.cut, client.closing
    (True, (4408, 'too slow: reconnect with since'))
    """

    key: Any
    maxsize: int = 2000
    queue: deque[Batch] = field(default_factory=deque)
    queued: int = 0
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    ended: asyncio.Event = field(default_factory=asyncio.Event)
    closing: tuple[int, str] | None = None
    sent: int = 0
    last_ping: datetime | None = None
    direct: FrameWriter | None = None
    max_unsent: int = MAX_UNSENT_BYTES

    @property
    def cut(self) -> bool:
        """``True`` once the server has decided to close the connection."""
        return self.closing is not None

    def offer(self, text: str) -> None:
        """Queue one encoded message, or cut the client if its queue is full."""
        self.offer_batch(Batch(text, 1, text))

    def offer_batch(self, batch: Batch) -> None:
        """Queue (or write) a batch, or cut the client if it is too far behind."""
        if self.closing is not None:
            return
        direct = self.direct
        if direct is not None:
            if direct.buffered() > self.max_unsent:
                self.close(CLOSE_TOO_SLOW, "too slow: reconnect with since")
            elif direct.write(batch.wire):
                self.sent += 1
            return
        if self.queued + batch.count > self.maxsize:
            self.close(CLOSE_TOO_SLOW, "too slow: reconnect with since")
            return
        self.queue.append(batch)
        self.queued += batch.count
        self.wake.set()

    def close(self, code: int, reason: str) -> None:
        """End the connection (its sender closes it with ``code``); queued messages are dropped."""
        if self.closing is None:
            self.closing = (code, reason)
            self.direct = None
            self.queue.clear()
            self.queued = 0
        self.wake.set()
        self.ended.set()

    def go_direct(self, writer: FrameWriter) -> bool:
        """Write to ``writer`` from now on, if nothing is queued (loop thread); ``True`` if so."""
        if self.queue or self.closing is not None:
            return False
        self.direct = writer
        return True

    def next_frame(self, limit: int = MAX_FRAME_MESSAGES) -> str | None:
        """Take the text of the next frame: everything queued (up to ``limit`` messages)."""
        if not self.queue:
            return None
        first = self.queue.popleft()
        if not self.queue or first.count + self.queue[0].count > limit:
            self.queued -= first.count
            return first.frame
        bodies = [first.body]
        count = first.count
        while self.queue and count + self.queue[0].count <= limit:
            batch = self.queue.popleft()
            bodies.append(batch.body)
            count += batch.count
        self.queued -= count
        return "[" + ",".join(bodies) + "]"


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
        self._pending: list[str] = []
        self._lock = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._following = False
        self.relay: Callable[[str, str], None] | None = None
        """Also hands each replayable message, encoded, to the other workers (the owner's)."""

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Deliver to clients on ``loop`` (``None``: no clients, messages only numbered)."""
        with self._lock:
            self._loop = loop
            self._pending.clear()

    def publish(self, message: Mapping[str, Any]) -> int | None:
        """Send ``message`` to every client; return its ``seq`` if it is replayable.

        Thread-safe and never blocks on a client: the text joins the pending
        batch, which the event loop hands to the clients' queues. A replayable
        message also goes to :attr:`relay` (the other workers), numbered.
        """
        replayable = message.get("type") in REPLAYED
        relay = self.relay
        with self._lock:
            seq = None
            if replayable:
                self.seq += 1
                seq = self.seq
                numbered = {**message, "seq": seq}
                self._ring.append((seq, numbered))
                message = numbered
            loop = self._loop
            if loop is None and (relay is None or not replayable):
                return seq
            # Encoded under the lock, so the pending texts stay in seq order.
            text = encode(message)
            if relay is not None and replayable:
                relay(self.rig_id, text)
            if loop is None:
                return seq
            self._pending.append(text)
            first = len(self._pending) == 1
        if first:
            _call_soon(loop, self.flush)
        return seq

    def publish_numbered(self, message: dict[str, Any], text: str) -> None:
        """Deliver a message another worker numbered and encoded (``text``), keeping its ``seq``."""
        seq = message.get("seq")
        with self._lock:
            if isinstance(seq, int):
                self._following = True
                self.seq = seq
                self._ring.append((seq, message))
            loop = self._loop
            if loop is None:
                return
            self._pending.append(text)
            first = len(self._pending) == 1
        if first:
            _call_soon(loop, self.flush)

    def follow(self, seq: int) -> None:
        """Take the owner's numbering (a worker that has not heard a message of this rig yet)."""
        with self._lock:
            if not self._following:
                self._following = True
                self.seq = seq

    def flush(self) -> None:
        """Hand the pending messages to every client, as one batch (loop thread)."""
        with self._lock:
            texts, self._pending = self._pending, []
            clients = list(self._clients)
        if texts:
            batch = Batch.of(texts)
            for client in clients:
                client.offer_batch(batch)

    def attach(self, client: LiveClient) -> int:
        """Add a client; return the ``seq`` it starts after (call in the loop thread).

        Messages published after this call reach the client's queue; those
        up to the returned number are for :meth:`replay_since`.
        """
        with self._lock:
            texts, self._pending = self._pending, []
            earlier = list(self._clients)
            self._clients.add(client)
            seq = self.seq
        if texts:  # published before the client came: only for the others
            batch = Batch.of(texts)
            for other in earlier:
                other.offer_batch(batch)
        return seq

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
        with self._lock:
            upto = self.seq if upto is None else upto
            kept = [m for s, m in self._ring if since < s <= upto]
            oldest = self._ring[0][0] if self._ring else self.seq + 1
        gap = since + 1 < oldest and since < upto
        return kept, gap

    def send_each(self, render: Callable[[LiveClient], dict[str, Any] | None]) -> None:
        """Send each client its own message (``render`` runs in the loop thread)."""

        def run() -> None:
            self.flush()  # what was published before goes first
            for client in self.clients():
                message = render(client)
                if message is not None:
                    client.offer(encode(message))

        loop = self._loop
        if loop is not None:
            _call_soon(loop, run)


def _call_soon(loop: asyncio.AbstractEventLoop, action: Callable[[], None]) -> None:
    """Run ``action`` on ``loop`` soon, from any thread (never at once: callers batch)."""
    if loop.is_closed():
        return
    try:
        running = asyncio.get_running_loop()
    except RuntimeError:
        running = None
    if running is loop:
        loop.call_soon(action)
    else:
        loop.call_soon_threadsafe(action)


class LiveFanout:
    """The live channels of every rig of a lab.

    Parameters
    ----------
    rig_ids : iterable of str
    """

    def __init__(self, rig_ids: Iterable[str]) -> None:
        self.channels = {rig_id: LiveChannel(rig_id) for rig_id in rig_ids}
        self._access_pending: set[str] = set()
        self._lock = threading.Lock()
        self.loop: asyncio.AbstractEventLoop | None = None

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Deliver on ``loop`` (the server's event loop)."""
        self.loop = loop
        for channel in self.channels.values():
            channel.bind(loop)

    def publish(self, rig_id: str, message: Mapping[str, Any]) -> None:
        """Publish on a rig's channel (unknown rigs are ignored)."""
        channel = self.channels.get(rig_id)
        if channel is not None:
            channel.publish(message)

    def clients(self) -> list[LiveClient]:
        """Every connected client of every rig."""
        return [client for channel in self.channels.values() for client in channel.clients()]

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
            # Unbound meanwhile: the server is stopping, and its loop may close before
            # a task started now would run (its coroutine then "never awaited").
            if self.loop is loop:
                refresh(rig_id)

        loop.call_soon_threadsafe(loop.call_later, delay, fire)
