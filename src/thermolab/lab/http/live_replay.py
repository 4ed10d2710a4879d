"""What a resuming live socket is sent of what it missed (``docs/live-protocol.md``, "Replay").

A client that connects with ``since`` gets the messages after it that the
rig's channel still keeps in memory; when memory no longer reaches back that
far, the current run's samples come from the store first. Both are bounded
and budgeted, so that one user replaying on every socket they may open slows
nobody else:

* **Paged.** The store is read a page at a time (keyset on the primary key
  ``(run_id, k)``, :data:`PAGE` rows a query, one ``samples`` frame a page),
  never the whole run, and at most ``limit`` samples a socket: the run's first
  sample (the page's model starts from it), then — when the run is longer —
  a ``truncated`` message saying where the newest begin, then the newest.
  A run with further channels (a kit's ``t2``, ``q2``, kept in the samples'
  ``extra``) has them in each item's ``channels``, as its live samples do, so
  a watcher who joins late sees their traces from the start; a one-channel
  run's pages are read and written as before, without them.
* **Off the event loop.** Pages are read and encoded in the thread pool, and
  at most ``concurrent`` replays read the store at once in the whole server;
  the event loop only hands finished frames to the socket.
* **A budget per user.** One replay at a time per user (however many sockets
  or logins they hold: the others wait their turn), paced to ``rate`` samples
  a second, and all replays together to ``server_rate``, yielding to the
  event loop between pages.
* **No hostage.** A frame the client does not take within
  :data:`SEND_TIMEOUT` seconds cuts it (4408, as a slow client), so a socket
  that stops reading cannot hold its user's turn.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import math
from collections.abc import AsyncIterator, Callable
from typing import Any, TypeVar

import anyio.to_thread
from starlette.websockets import WebSocket

from thermolab.lab.http.live_messages import SamplesMessage, TruncatedMessage
from thermolab.lab.live.fanout import CLOSE_TOO_SLOW, MAX_FRAME_MESSAGES, LiveChannel, encode
from thermolab.lab.runs.export import RunExport

__all__ = ["PAGE", "SEND_TIMEOUT", "ReplayBudget", "ReplayTooSlowError", "replay"]

PAGE = MAX_FRAME_MESSAGES
"""Stored samples read by one query and sent in one ``samples`` frame."""
SEND_TIMEOUT = 10.0
"""Seconds a replay frame may wait for the client to take it before the client is cut."""

_T = TypeVar("_T")


class ReplayTooSlowError(Exception):
    """The client did not take a replay frame in time (close it with 4408)."""


class ReplayBudget:
    """Replays in the whole server: one at a time per user, a few reading the store, paced.

    Parameters
    ----------
    concurrent : int
        Replays reading the store (in the thread pool) at once, server-wide.
    rate : float
        Samples a second one user's replay is sent at most.
    server_rate : float
        Samples a second all replays together are sent at most (so that many
        users, or accounts, replaying at once cost no more than two would).
    """

    def __init__(
        self, *, concurrent: int = 2, rate: float = 20_000.0, server_rate: float = 40_000.0
    ) -> None:
        self.concurrent = concurrent
        self.rate = rate
        self.server_rate = server_rate
        self.bind()

    def bind(self) -> None:
        """Start afresh (the server's event loop starts: its locks are new)."""
        self._server_free = 0.0  # when the server's replay rate has room again (loop time)
        self._reading = asyncio.Semaphore(self.concurrent)
        self._turns: dict[int, asyncio.Lock] = {}
        self._waiting: collections.Counter[int] = collections.Counter()

    @contextlib.asynccontextmanager
    async def turn(self, user_id: int) -> AsyncIterator[None]:
        """Wait for, then hold, the user's one replay at a time."""
        lock = self._turns.setdefault(user_id, asyncio.Lock())
        self._waiting[user_id] += 1
        try:
            async with lock:
                yield
        finally:
            self._waiting[user_id] -= 1
            if self._waiting[user_id] <= 0:
                del self._waiting[user_id]
                del self._turns[user_id]

    async def read(self, action: Callable[..., _T], *args: Any) -> _T:
        """Run ``action(*args)`` in the thread pool, as one of the ``concurrent`` readers."""
        async with self._reading:
            return await anyio.to_thread.run_sync(action, *args)

    async def pace(self, started: float, sent: int, count: int) -> None:
        """Wait until the replay's ``sent`` samples since ``started`` (``count`` of them
        just now) are within the user's rate and the server's (and yield to the loop)."""
        now = asyncio.get_running_loop().time()
        # Every replay's pages take turns on one server-wide timeline.
        self._server_free = max(now, self._server_free) + count / self.server_rate
        until = max(started + sent / self.rate, self._server_free)
        await asyncio.sleep(max(0.0, until - now))


async def replay(
    websocket: WebSocket,
    channel: LiveChannel,
    store: RunExport,
    run_id: int | None,
    since: int,
    upto: int,
    *,
    user_id: int,
    budget: ReplayBudget,
    limit: int,
) -> None:
    """Send what a client that had ``since`` missed up to ``upto``, within the budget.

    Raises
    ------
    ReplayTooSlowError
        If the client did not take a frame within :data:`SEND_TIMEOUT`.
    """
    async with budget.turn(user_id):
        if since > upto:
            # A number this server never gave (the clock was set back across a restart):
            # what the client has is unknown, so it gets the current run from the store.
            kept: list[dict[str, Any]] = []
            gap = True
        else:
            kept, gap = channel.replay_since(since, upto)
        loop = asyncio.get_running_loop()
        started = loop.time()
        sent = 0
        if gap and run_id is not None:
            # Memory no longer has everything missed: the current run's samples from the store.
            sent = await _send_stored(websocket, store, run_id, budget, limit, started)
        # Then what memory keeps, in the order it happened (encoded off the event loop).
        for frame, count in await anyio.to_thread.run_sync(_kept_frames, kept):
            await _send(websocket, frame)
            sent += count
            await budget.pace(started, sent, count)


async def _send_stored(
    websocket: WebSocket,
    store: RunExport,
    run_id: int,
    budget: ReplayBudget,
    limit: int,
    started: float,
) -> int:
    """Send the run's stored samples (at most ``limit``) page by page; return how many."""
    span = await budget.read(_stored_span, store, run_id, limit)
    if span is None:
        return 0
    first, start, last, further = span
    sent = 0
    after: int | None = None
    if start > first + 1:
        # Too long for one socket: the first sample (where the run started from), a
        # notice of what is skipped, then the newest samples.
        page = await budget.read(_stored_frame, store, run_id, None, first, 1, further)
        assert page is not None
        await _send(websocket, page[0])
        truncated: TruncatedMessage = {
            "type": "truncated",
            "run": run_id,
            "from": start,
            "limit": limit,
        }
        await _send(websocket, encode(truncated))
        sent, after = 1, start - 1
    while True:
        page = await budget.read(_stored_frame, store, run_id, after, last, PAGE, further)
        if page is None:
            return sent
        frame, after, count = page
        await _send(websocket, frame)
        sent += count
        await budget.pace(started, sent, count)


def _stored_span(
    store: RunExport, run_id: int, limit: int
) -> tuple[int, int, int, tuple[str, ...]] | None:
    """``(first k, first k sent after it, last k, further channels)`` of a replay of at most
    ``limit`` samples; the further channels are the names the run keeps in ``extra``."""
    newest = store.newest_samples(run_id, max(1, limit - 1))
    if newest is None:
        return None
    head = store.sample_page(run_id, None, 1)
    return head[0][0], newest[0], newest[1], store.further_channels(run_id)


def _stored_frame(
    store: RunExport,
    run_id: int,
    after: int | None,
    upto: int,
    rows: int,
    further: tuple[str, ...] = (),
) -> tuple[str, int, int] | None:
    """One page of stored samples as a ``samples`` frame: ``(text, last k, count)``.

    A run with ``further`` channels (a kit's ``t2`` and ``q2``) has them in each
    item's ``channels``, as its live samples do; a one-channel run's pages are
    read and written without them (the common case, and the replay's main cost).
    """
    if further:
        return _stored_frame_with_channels(store, run_id, after, upto, rows, further)
    page = store.sample_page(run_id, after, rows, upto)
    if not page:
        return None
    # Written directly (the shape of SamplesMessage without seq): four numbers a row
    # need no general encoder, and this is the replay's main cost.
    items = ",".join(
        f'{{"run":{run_id},"k":{k},"t":{_number(t)},"u":{_number(u)},"y":{_number(y)}}}'
        for k, t, u, y in page
    )
    return f'{{"type":"samples","items":[{items}]}}', page[-1][0], len(page)


def _stored_frame_with_channels(
    store: RunExport, run_id: int, after: int | None, upto: int, rows: int, further: tuple[str, ...]
) -> tuple[str, int, int] | None:
    """:func:`_stored_frame` for a run with further channels: each item with ``channels``."""
    page = store.sample_page_with_extra(run_id, after, rows, upto)
    if not page:
        return None
    keys = [(name, json.dumps(name)) for name in further]  # names as JSON strings, once a page

    def item(k: int, t: float, u: float, y: float, extra: dict[str, float | None] | None) -> str:
        stored = extra or {}
        channels = ",".join(f"{key}:{_number(stored.get(name))}" for name, key in keys)
        return (
            f'{{"run":{run_id},"k":{k},"t":{_number(t)},"u":{_number(u)},"y":{_number(y)},'
            f'"channels":{{{channels}}}}}'
        )

    items = ",".join(item(*row) for row in page)
    return f'{{"type":"samples","items":[{items}]}}', page[-1][0], len(page)


def _number(value: float | None) -> str:
    """A JSON number as :func:`~thermolab.lab.live.fanout.encode` writes it (non-finite: null).

    >>> _number(0.1), _number(float("nan")), _number(None)
    ('0.1', 'null', 'null')
    """
    return repr(float(value)) if value is not None and math.isfinite(value) else "null"


def _kept_frames(kept: list[dict[str, Any]]) -> list[tuple[str, int]]:
    """The kept messages as frames, in order: runs of samples as ``samples`` batches."""
    frames: list[tuple[str, int]] = []
    batch: list[dict[str, Any]] = []
    for message in [*kept, None]:
        if message is not None and message["type"] == "sample":
            batch.append({k: v for k, v in message.items() if k != "type"})
            if len(batch) < PAGE:
                continue
        if batch:
            samples: SamplesMessage = {"type": "samples", "seq": batch[-1]["seq"], "items": batch}
            frames.append((encode(samples), len(batch)))
            batch = []
        if message is not None and message["type"] != "sample":
            frames.append((encode(message), 1))
    return frames


async def _send(websocket: WebSocket, frame: str) -> None:
    try:
        await asyncio.wait_for(websocket.send_text(frame), SEND_TIMEOUT)
    except TimeoutError:
        raise ReplayTooSlowError(CLOSE_TOO_SLOW) from None
