"""A few joiners per turn of the event loop, so that a storm of them delays no sample.

A lecture hall's pages all reconnect after a restart, or a class opens the rig
at the bell: a thousand WebSocket connections reach the server within a second.
Each one's way into the live stream (the ASGI stack: middleware, route
matching, the accept and its log line; then its ``hello``) is a few hundred
microseconds of the event loop's time. Left alone, every joiner's task is
ready at once, and the event loop runs ready callbacks first come, first
served: a sample published meanwhile (its flush scheduled from the sampling
thread) waited behind all of them, up to 0.8 s (``benchmarks/bench_join_storm.py``).

A :class:`Turnstile` lets at most ``per_turn`` callers through each turn of
the loop; the others wait, in order, for the turns that follow. A turn ends
with a callback scheduled behind the ones already ready, so whatever became
ready meanwhile (a sample's flush, the readings of the sockets' I/O) runs
before the next joiners: the stream's watchers wait for a few joiners at
most, never for all of them. A joiner that finds no queue and a free place
goes through at once, without a wait.

:func:`loop_turnstile` is the running loop's turnstile, shared by every place
a joiner passes: ``thermolab serve``'s WebSocket upgrade and ASGI call, the live
endpoint once the joiner's login is known and before its ``hello`` is sent.
"""

from __future__ import annotations

import asyncio
import weakref
from collections import deque

__all__ = ["PER_TURN", "Turnstile", "loop_turnstile", "take_turn"]

PER_TURN = 8
"""Joiners let through per turn of the event loop: a few milliseconds of its time."""


class Turnstile:
    """Lets at most ``per_turn`` callers through per turn of the event loop (loop thread).

    Parameters
    ----------
    per_turn : int
        How many :meth:`turn` calls return per turn of the loop.

    Examples
    --------
    >>> async def main():
    ...     gate, through = Turnstile(per_turn=2), []
    ...
    ...     async def joiner(n):
    ...         await gate.turn()
    ...         through.append(n)
    ...
    ...     tasks = [asyncio.ensure_future(joiner(n)) for n in range(5)]
    ...     await asyncio.sleep(0)  # one turn of the loop: the first two are through
    ...     first = list(through)
    ...     await asyncio.gather(*tasks)
    ...     return first, through
    >>> asyncio.run(main())
    ([0, 1], [0, 1, 2, 3, 4])
    """

    def __init__(self, per_turn: int = PER_TURN) -> None:
        if per_turn < 1:
            raise ValueError("a turnstile lets at least one caller through per turn")
        self.per_turn = per_turn
        self._passed = 0  # callers let through this turn
        self._waiting: deque[asyncio.Future[None]] = deque()
        self._next_scheduled = False

    @property
    def waiting(self) -> int:
        """Callers waiting for a turn."""
        return len(self._waiting)

    async def turn(self) -> None:
        """Return in this turn of the loop if there is a place in it, else in a later one."""
        future = self.place()
        if future is not None:
            await future  # a cancelled waiter is skipped by _next_turn: it takes no place

    def place(self) -> asyncio.Future[None] | None:
        """A place: ``None`` if it is in this turn, else a future done in the turn that has it.

        For callbacks (a protocol's); cancel the future to give the place up.
        """
        if not self._waiting and self._passed < self.per_turn:
            self._passed += 1
            self._schedule_next()
            return None
        future: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._waiting.append(future)
        self._schedule_next()
        return future

    def _schedule_next(self) -> None:
        if not self._next_scheduled:
            self._next_scheduled = True
            # Behind every callback already ready: what became ready before it runs first.
            asyncio.get_running_loop().call_soon(self._next_turn)

    def _next_turn(self) -> None:
        self._next_scheduled = False
        self._passed = 0
        while self._waiting and self._passed < self.per_turn:
            future = self._waiting.popleft()
            if not future.done():
                future.set_result(None)
                self._passed += 1
        if self._passed:  # the places it gave count until the turn after
            self._schedule_next()


_turnstiles: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, Turnstile] = (
    weakref.WeakKeyDictionary()
)


def loop_turnstile() -> Turnstile:
    """The running loop's turnstile (one per loop, shared by all joiners)."""
    loop = asyncio.get_running_loop()
    turnstile = _turnstiles.get(loop)
    if turnstile is None:
        turnstile = _turnstiles[loop] = Turnstile()
    return turnstile


async def take_turn() -> None:
    """Wait for a place in the running loop's turnstile."""
    await loop_turnstile().turn()
