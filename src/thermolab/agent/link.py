"""The agent's link to its lab: dial out, authenticate, send, obey, redial.

One asyncio task per connection does three things: it sends the outbox in
``seq`` order (everything unacknowledged, again, after each reconnection),
a :class:`~thermolab.agent.protocol.Heartbeat` every ``heartbeat`` seconds,
and hands the lab's commands to the :class:`~thermolab.agent.host.RigHost`
(in a worker thread: a TCLab command may block for a while).

The connection is the ``websockets`` library's client (already the lab's
live-stream dependency): TLS with the lab's CA (``ssl`` from the standard
library), and its own ping every ``ping`` seconds, so that a lab that stops
answering (a paused process, a cut cable: TCP would wait for minutes) is
noticed within ``ping`` + ``ping_timeout`` seconds. Then the host is told
(:meth:`RigHost.link_lost`) and the agent dials again with exponential
backoff (0.5 s doubling up to ``max_backoff``, with jitter) until the lab
answers; nothing listens on the rig host.

A lab of several web workers (docs/fleet.md) is given as several addresses
(``url`` and ``others``): the agent dials them in turn. A worker that does
not own the rigs closes the link with
:data:`~thermolab.agent.protocol.CLOSE_NOT_OWNER`, and so does one that has
just lost the lease; the agent then dials the next address at once, so it
finds the owner — the first one, or the follower that took over — within a
round of its list.
"""

from __future__ import annotations

import asyncio
import logging
import os
import random
import secrets
import socket
import ssl
from dataclasses import dataclass

import websockets
from pydantic import ValidationError
from websockets.asyncio.client import ClientConnection, connect

from thermolab import __version__
from thermolab.agent.host import RigHost
from thermolab.agent.protocol import (
    CLOSE_NOT_OWNER,
    CLOSE_REFUSED,
    PROTOCOL_VERSION,
    Ack,
    EndRun,
    Hello,
    Power,
    SetFan,
    SetGains,
    SetInput,
    SetMode,
    SetSetpoint,
    StartRun,
    Welcome,
    decode_lab,
    encode,
)
from thermolab.errors import ThermoLabError

__all__ = ["AgentLink", "LinkSettings", "RefusedError", "outbox_frames"]

log = logging.getLogger(__name__)

_BATCH = 500


class RefusedError(ThermoLabError):
    """The lab refused the agent (unknown rig, wrong secret, other protocol)."""


class _NotOwnerError(Exception):
    """The worker dialled does not own the rigs: dial the next address."""


@dataclass(frozen=True, slots=True)
class LinkSettings:
    """How the agent reaches its lab.

    Attributes
    ----------
    url : str
        ``wss://HOST:PORT/api/agents/link`` (``ws://`` only on loopback tests).
    others : tuple of str
        The lab's other web workers' link addresses, dialled in turn after ``url``.
    rig : str
        The rig id the lab knows this host by.
    secret : str
        The rig's secret, issued by ``thermolab agent-secret RIG`` on the lab.
    spec : str
        What the rig is (shown on the lab's status page).
    cafile : str or None
        CA certificate(s) to trust for the lab (default: the system's).
    heartbeat, ping, ping_timeout, max_backoff : float
        Seconds.
    speedup : float
        Times real time the host's rig runs (``--speedup`` of a twin), told in ``Hello``
        so that the lab counts a run's real length and publishes the pace.
    """

    url: str
    rig: str
    secret: str
    spec: str
    others: tuple[str, ...] = ()
    cafile: str | None = None
    heartbeat: float = 1.0
    ping: float = 1.0
    ping_timeout: float = 3.0
    max_backoff: float = 10.0
    speedup: float = 1.0


class AgentLink:
    """Keeps a rig host connected to its lab, for as long as :meth:`run` runs."""

    def __init__(self, host: RigHost, settings: LinkSettings) -> None:
        self.host = host
        self.settings = settings
        self.connected = asyncio.Event()
        self._wake = asyncio.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._turn = 0  # which of the lab's addresses is dialled next
        # Who this process is, the same on every redial: the lab refuses a second host
        # for a rig it already has, and lets this one replace a link it lost.
        self.host_id = f"{socket.gethostname()}:{os.getpid()}:{secrets.token_hex(4)}"

    @property
    def url(self) -> str:
        """The address dialled now (one of ``settings.url`` and ``settings.others``)."""
        urls = (self.settings.url, *self.settings.others)
        return urls[self._turn % len(urls)]

    def wake(self) -> None:
        """Something was added to the outbox (called from any thread)."""
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._wake.set)

    async def run(self) -> None:
        """Dial, serve, redial with backoff, forever (cancel the task to stop)."""
        self._loop = asyncio.get_running_loop()
        backoff = 0.5
        addresses = 1 + len(self.settings.others)
        while True:
            try:
                await self._session()
                backoff = 0.5
            except RefusedError:
                raise
            except _NotOwnerError:
                self._turn += 1
                if self._turn % addresses:  # the next worker at once, a pause after a round
                    continue
            except (OSError, websockets.exceptions.WebSocketException, TimeoutError) as exc:
                log.warning("link to %s: %s", self.url, exc)
                self._turn += 1
            finally:
                if self.connected.is_set():
                    self.connected.clear()
                    self.host.link_lost()
            delay = backoff * (0.5 + random.random() / 2)
            await asyncio.sleep(delay)
            backoff = min(backoff * 2, self.settings.max_backoff)

    def _ssl(self) -> ssl.SSLContext | None:
        if not self.url.startswith("wss://"):
            return None
        return ssl.create_default_context(cafile=self.settings.cafile)

    async def _session(self) -> None:
        s = self.settings
        url = self.url
        async with connect(
            url,
            ssl=self._ssl(),
            ping_interval=s.ping,
            ping_timeout=s.ping_timeout,
            open_timeout=10,
            close_timeout=2,
            max_size=2**20,
        ) as ws:
            hello = Hello(
                rig=s.rig,
                secret=s.secret,
                protocol=PROTOCOL_VERSION,
                version=__version__,
                spec=s.spec,
                speedup=s.speedup,
                host=self.host_id,
            )
            await ws.send(encode(hello))
            try:
                first = decode_lab(await asyncio.wait_for(ws.recv(), 10))
            except websockets.exceptions.ConnectionClosed as exc:
                if exc.rcvd is not None and exc.rcvd.code == CLOSE_REFUSED:
                    raise RefusedError(
                        f"the lab refused rig {s.rig!r}: {exc.rcvd.reason}"
                    ) from None
                if exc.rcvd is not None and exc.rcvd.code == CLOSE_NOT_OWNER:
                    log.info("%s does not own the rigs: dialling the next worker", url)
                    raise _NotOwnerError from None
                raise
            if not isinstance(first, Welcome):
                raise websockets.exceptions.InvalidMessage(f"expected welcome, got {first.type}")
            self.host.grace = first.grace
            self.host.link_back()
            self.connected.set()
            log.info("linked to %s as rig %s", url, s.rig)
            tasks = [
                asyncio.create_task(self._send(ws)),
                asyncio.create_task(self._beat(ws)),
                asyncio.create_task(self._receive(ws)),
            ]
            try:
                done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
                for task in done:
                    task.result()  # raise what ended the session
            finally:
                for task in tasks:
                    task.cancel()
                await asyncio.gather(*tasks, return_exceptions=True)

    async def _send(self, ws: ClientConnection) -> None:
        sent = 0  # this connection resends the whole outbox from its start
        while True:
            self._wake.clear()
            rows = await asyncio.to_thread(self.host.outbox.pending, sent, _BATCH)
            if not rows:
                await self._wake.wait()
                continue
            for frame in outbox_frames(rows):
                await ws.send(frame)
            sent = rows[-1][0]

    async def _beat(self, ws: ClientConnection) -> None:
        while True:
            beat = await asyncio.to_thread(self.host.heartbeat)
            await ws.send(encode(beat))
            await asyncio.sleep(self.settings.heartbeat)

    async def _receive(self, ws: ClientConnection) -> None:
        async for frame in ws:
            try:
                message = decode_lab(frame)
            except ValidationError as exc:
                log.warning("ignored a message the lab sent: %s", exc.errors()[:1])
                continue
            try:
                if isinstance(message, Ack):
                    await asyncio.to_thread(self.host.outbox.ack, message.seq)
                elif isinstance(message, StartRun):
                    try:
                        await asyncio.to_thread(self.host.start_run, message)
                    except ThermoLabError as exc:
                        await asyncio.to_thread(self.host.refuse_run, message.run, str(exc))
                        raise
                elif isinstance(message, EndRun):
                    await asyncio.to_thread(self.host.end_run, message.run)
                elif isinstance(message, SetInput):
                    await asyncio.to_thread(self.host.set_input, message.u, message.run)
                elif isinstance(message, Power):
                    await asyncio.to_thread(self.host.power, message.on)
                elif isinstance(message, SetMode | SetSetpoint | SetGains | SetFan):
                    await asyncio.to_thread(self.host.command, message)
            except ThermoLabError as exc:
                log.warning("%s refused: %s", message.type, exc)


def outbox_frames(rows: list[tuple[int, str, str]]) -> list[str]:
    """The frames that carry outbox rows ``(seq, kind, body)``, in ``seq`` order.

    Consecutive samples go in one :class:`~thermolab.agent.protocol.SampleBatch`;
    a run's end is a frame of its own after its last sample. Each body gets
    its ``seq`` (the outbox stores bodies without it).
    """
    frames: list[str] = []
    samples: list[str] = []
    for seq, kind, body in rows:
        framed = body[:-1] + f',"seq":{seq}}}'
        if kind == "sample":
            samples.append(framed)
            continue
        if samples:
            frames.append(_batch(samples))
            samples = []
        frames.append(framed)  # a run's end, after its last sample
    if samples:
        frames.append(_batch(samples))
    return frames


def _batch(samples: list[str]) -> str:
    return '{"type":"samples","samples":[' + ",".join(samples) + "]}"
