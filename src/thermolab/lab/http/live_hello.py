"""The live stream's ``hello``, read once for every client that joins meanwhile.

A lecture hall's pages all join a rig at once after a restart, or a class opens
it at the bell. Read for each joiner, a hello cost three store round trips
(who it is aside): 1,000 joiners then waited up to 14 s on the live sockets'
few threads, and that store work, holding the GIL, delayed the samples of
those already watching by up to 270 ms (``benchmarks/bench_join_storm.py``).

Joiners that come while a rig's hello is being read wait for the next reading,
which serves them all: the rig's state and its run are read once, after every
joiner of the batch was attached to the stream (so no hello is older than its
client's place in the stream), and rendered once per viewpoint (a watcher, a
teacher watching, the controller, each queued user). Whoever holds a control or
queue place has their hello read as before, on its own: it is the heartbeat
that keeps the place.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any

from thermolab.lab.accounts.users import Principal
from thermolab.lab.http.routers.runs import RunOut
from thermolab.lab.http.schemas import RigOut, people_named
from thermolab.lab.live.fanout import encode
from thermolab.lab.service import Lab

__all__ = ["HelloReader"]

InThread = Callable[..., Awaitable[Any]]

_SEQ_LAST = '"seq":null}'
"""How an encoded hello ends before its client's ``seq`` is put in (``seq`` is its last key)."""


class HelloReader:
    """Reads each rig's hello for the clients that join, in batches (loop thread).

    Parameters
    ----------
    lab : Lab
    in_thread : callable
        Runs store work in a worker thread: ``await in_thread(work, *args)``.
    """

    def __init__(self, lab: Lab, in_thread: InThread) -> None:
        self._lab = lab
        self._in_thread = in_thread
        self._waiting: dict[str, list[tuple[Principal, asyncio.Future[str]]]] = {}
        self._readers: dict[str, asyncio.Task[None]] = {}

    async def hello(self, rig_id: str, who: Principal, seq: int) -> str:
        """The encoded ``hello`` of a client attached to the rig's stream after ``seq``."""
        future: asyncio.Future[str] = asyncio.get_running_loop().create_future()
        self._waiting.setdefault(rig_id, []).append((who, future))
        if rig_id not in self._readers:
            self._readers[rig_id] = asyncio.ensure_future(self._read(rig_id))
        text = await future
        return f'{text[: -len(_SEQ_LAST)]}"seq":{seq}}}'

    async def _read(self, rig_id: str) -> None:
        try:
            while batch := self._waiting.pop(rig_id, None):
                batch = [(who, future) for who, future in batch if not future.done()]
                try:
                    texts = await self._in_thread(self._render, rig_id, [w for w, _ in batch])
                except Exception as exc:  # every member's hello fails as its own would have
                    for _, future in batch:
                        if not future.done():
                            future.set_exception(exc)
                    continue
                for (_, future), text in zip(batch, texts, strict=True):
                    if not future.done():  # its client may have gone meanwhile
                        future.set_result(text)
        finally:
            del self._readers[rig_id]

    def _render(self, rig_id: str, members: list[Principal]) -> list[str]:
        """Each member's hello (``seq`` null), from one reading of the rig (a worker thread)."""
        lab = self._lab
        if not members:
            return []
        # The first member's view: their heartbeat if they hold a place, and any limit
        # that has run out applied before the rig is shown to anyone.
        first = lab.access.view(rig_id, members[0])
        snap = first.snapshot or lab.access.snapshot(rig_id)
        run_id = lab.running(rig_id)
        run = None
        if run_id is not None:
            record = lab.runs.record(run_id)
            run = _dump(RunOut.of(record, lab.names.names([record.username])))
        watchers = lab.presence.watchers(rig_id)
        shown: dict[bool, str] = {}  # a plain watcher's hello, a teacher's and a student's
        texts = []
        for index, who in enumerate(members):
            holds_place = (
                snap.controller is not None and snap.controller.user_id == who.user_id
            ) or snap.slot_of(who.user_id) is not None
            if index == 0:
                view = first  # read above, with its heartbeat and presence
            elif holds_place:  # their hello is their place's heartbeat, as a ping is
                view = lab.access.view(rig_id, who)
            else:
                lab.presence.touch(rig_id, who.username)  # watching, as a view notes
                if who.is_teacher in shown:
                    texts.append(shown[who.is_teacher])
                    continue
                view = lab.access.render(snap, who, watchers)
            rig = _dump(RigOut.of(view, lab.names.names(people_named(view))))
            text = encode(
                {"type": "hello", "rig": rig, "access": rig["access"], "run": run, "seq": None}
            )
            if not text.endswith(_SEQ_LAST):  # pragma: no cover - encode's order is the dict's
                raise AssertionError("a hello must end with its seq")
            if not holds_place:
                shown[who.is_teacher] = text
            texts.append(text)
        return texts


def _dump(model: RigOut | RunOut) -> dict[str, Any]:
    return model.model_dump(mode="json", by_alias=True)
