"""A standby busy taking over while it holds a host's Hello keeps the host (issue #23).

A standby holds the Hello of a host that dials it during a takeover, and is
busiest then (opening the rigs, adopting the runs): its pongs may come late,
and with its usual keepalive (a 2-3 s timeout) the host would drop the very
link it is held on and go round its list again, spending its grace. Until the
Welcome the host waits 10 s for a pong (``HELLO_PING_TIMEOUT``). Here a
WebSocket server reads the Hello, then blocks its own event loop for 5 s (no
pong can go out), then answers ``Welcome``: the agent must be linked on that
first connection. (A standby that never read the held Hello answered no ping
at all: tests/lab/test_forward.py.)
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Iterator

from websockets.asyncio.server import ServerConnection, serve

from thermolab.agent.host import RigHost
from thermolab.agent.link import AgentLink, LinkSettings
from thermolab.agent.outbox import Outbox
from thermolab.agent.protocol import Welcome, encode
from thermolab.rigs import RigSpec, make_clock

BUSY = 5.0
"""Seconds the 'standby' stalls with the Hello unanswered: over the pings' 2 s timeout."""


@contextlib.contextmanager
def _busy_standby() -> Iterator[tuple[str, list[str]]]:
    """A server that stalls ``BUSY`` s before its Welcome; yields its address and its log."""
    seen: list[str] = []
    ready = threading.Event()
    stop = threading.Event()
    address: list[str] = []

    async def handler(ws: ServerConnection) -> None:
        await ws.recv()  # the Hello
        seen.append("hello")
        time.sleep(BUSY)  # blocking on purpose: its loop answers no ping meanwhile
        await ws.send(encode(Welcome(grace=30.0)))
        seen.append("welcome")
        with contextlib.suppress(Exception):
            async for _ in ws:
                pass

    async def main() -> None:
        async with serve(handler, "127.0.0.1", 0) as server:
            port = next(iter(server.sockets)).getsockname()[1]
            address.append(f"ws://127.0.0.1:{port}/api/agents/link")
            ready.set()
            while not stop.is_set():
                await asyncio.sleep(0.05)

    thread = threading.Thread(target=asyncio.run, args=(main(),), daemon=True)
    thread.start()
    assert ready.wait(10)
    try:
        yield address[0], seen
    finally:
        stop.set()
        thread.join(10)


def test_a_host_held_by_a_busy_standby_stays_on_that_link_until_its_welcome() -> None:
    rig = RigSpec.parse("sim:tclab").open(clock=make_clock(1.0))
    host = RigHost(rig, Outbox(":memory:"), grace=30.0)
    with _busy_standby() as (url, seen):
        # The agent command's settings: a ping a second, its pong due within 2 s.
        settings = LinkSettings(
            url=url, rig="box", secret="s" * 32, spec="sim:tclab", ping=1.0, ping_timeout=2.0
        )
        link = AgentLink(host, settings)

        async def until_linked() -> None:
            dialling = asyncio.create_task(link.run())
            try:
                await asyncio.wait_for(link.connected.wait(), BUSY + 15)
            finally:
                dialling.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await dialling

        try:
            asyncio.run(until_linked())
        finally:
            host.close()
        # Linked on its first dial: the held link was kept, not dropped and dialled again.
        assert seen[:2] == ["hello", "welcome"], seen
        assert seen.count("hello") == 1, seen
