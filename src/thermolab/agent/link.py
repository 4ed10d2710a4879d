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
noticed within ``ping`` + ``ping_timeout`` seconds (:data:`HELLO_PING_TIMEOUT` while
a standby holds its Hello through a takeover). Then the host is told
(:meth:`RigHost.link_lost`) and the agent dials again; nothing listens on
the rig host.

How soon it dials again depends on why the link failed, which a bare TCP
connection to each of the lab's addresses (a *probe*: no TLS, no request) tells:

* an address **answers** (the lab is there, and refused or broke the link):
  exponential back-off (0.5 s doubling up to ``max_backoff``, with jitter),
  so that a lab in trouble is not hammered by its hosts;
* **no address answers** (the network is away, or the lab is down): the
  agent probes them all every :data:`PROBE_EVERY` seconds, each probe given
  :data:`PROBE_TIMEOUT` and overlapping the next, and dials the first that
  connects at once — the back-off starts again from 0.5 s, since the network came
  back. A probe that goes nowhere costs the lab nothing, and one that a
  stopped lab's machine refuses costs it only a TCP reset; a dial, by
  contrast, can hang for seconds on a dropped SYN after the cable is back.
  The host is thus linked again within about a second of its network (or
  lab) returning, however long it was away. A probe goes where a dial's
  first step goes: the lab's address, or the proxy a dial would use
  (``HTTPS_PROXY`` and the like, as the ``websockets`` client reads them).

A lab of several web workers (docs/fleet.md) is given as several addresses
(``url`` and ``others``): the agent dials them in turn. A worker that does
not own the rigs closes the link with
:data:`~thermolab.agent.protocol.CLOSE_NOT_OWNER`, and so does one that has
just lost the lease; the agent then dials the next address at once, so it
finds the owner — the first one, or the follower that took over — within a
round of its list. A standby dialled while no owner is heard (a takeover)
holds the link instead, up to :data:`~thermolab.agent.protocol.HELLO_HOLD`,
and answers it as the new owner once it has taken over.

The same tries tell the host why a run it ENDs at its grace's end ended
(:meth:`RigHost.lab_answered`): if the last try of some address reached the
lab's machine — a worker closed the link as not the owner, the connection was
refused (nothing listens: the worker died) or accepted and left unanswered (a
hung worker) — the owner worker was gone (``OWNER_GONE``); if none reached
anything (timeouts, no route), the link was lost (``LINK_LOST``). A lab
machine that is itself down looks like a lost link: from the host, the two
cannot be told apart.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import random
import secrets
import socket
import ssl
from asyncio import FIRST_COMPLETED
from dataclasses import dataclass

import websockets
from pydantic import ValidationError
from websockets.asyncio.client import ClientConnection, connect
from websockets.proxy import get_proxy, parse_proxy
from websockets.uri import parse_uri

from thermolab import __version__
from thermolab.agent.host import RigHost
from thermolab.agent.protocol import (
    CLOSE_NOT_OWNER,
    CLOSE_REFUSED,
    HELLO_HOLD,
    PROTOCOL_VERSION,
    Ack,
    EndRun,
    Hello,
    Power,
    SetChannel,
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

__all__ = [
    "HELLO_PING_TIMEOUT",
    "PROBE_EVERY",
    "PROBE_TIMEOUT",
    "AgentLink",
    "LinkSettings",
    "RefusedError",
    "outbox_frames",
]

log = logging.getLogger(__name__)

_BATCH = 500

PROBE_EVERY = 0.25
"""Seconds between probes of a lab's address that did not answer."""

PROBE_TIMEOUT = 1.5
"""Seconds a probe waits for the lab's address to accept a TCP connection."""

HELLO_PING_TIMEOUT = 10.0
"""Seconds a ping may wait for its pong before the lab answers the Hello (a standby taking
over is busy); after the ``Welcome``, ``LinkSettings.ping_timeout``."""


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
        # Which addresses answered their last try (a dial or a probe) while the link is
        # down: the host's END at its grace's end names the cause from it (owner gone, or
        # the link lost: RigHost.lab_answered).
        self._answers: dict[int, bool] = {}
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
                self._answered(self._turn, True)
                self._turn += 1
                if self._turn % addresses:  # the next worker at once, a pause after a round
                    continue
            except (OSError, websockets.exceptions.WebSocketException, TimeoutError) as exc:
                log.warning("link to %s: %s", self.url, exc)
                # Refused (nothing listens) or answered in HTTP: the lab's machine is there.
                if isinstance(exc, ConnectionRefusedError | websockets.exceptions.InvalidStatus):
                    self._answered(self._turn, True)
                self._turn += 1
            finally:
                if self.connected.is_set():
                    self.connected.clear()
                    self.host.link_lost()
            if await self._answering(once=True) is not None:
                # The lab is there and the link failed anyway: back off for the lab's sake.
                await asyncio.sleep(backoff * (0.5 + random.random() / 2))
                backoff = min(backoff * 2, self.settings.max_backoff)
                continue
            # No address answers: the network (or the lab) is away. Dial the first to return.
            self._turn = await self._answering(once=False) or 0
            log.info("%s answers again: dialling it", self.url)
            backoff = 0.5  # the network came back: what failed before says nothing now
            # A little jitter: every host of a lab whose network came back would dial at once.
            await asyncio.sleep(random.random() * PROBE_EVERY)

    def _answered(self, index: int, answers: bool) -> None:
        """Address ``index`` answered its last try or not; the host hears whether any did."""
        addresses = 1 + len(self.settings.others)
        self._answers[index % addresses] = answers
        self.host.lab_answered(any(self._answers.values()))

    async def _answering(self, *, once: bool) -> int | None:
        """Which lab address accepts a TCP connection: one round of probes, or until one does.

        Every address is probed at once; ``once=False`` starts a round every
        :data:`PROBE_EVERY` seconds, each overlapping the next, until a probe
        connects. Returns that address's index (``None`` if one round found none).
        """
        hops = [_first_hop(url) for url in (self.settings.url, *self.settings.others)]
        answered: asyncio.Future[int] = asyncio.get_running_loop().create_future()

        async def probe(index: int) -> None:
            try:
                _, writer = await asyncio.wait_for(
                    asyncio.open_connection(*hops[index]), PROBE_TIMEOUT
                )
            except ConnectionRefusedError:
                self._answered(index, True)  # the machine answers: its worker is gone
                return
            except (OSError, TimeoutError):
                self._answered(index, False)
                return
            self._answered(index, True)
            writer.close()
            if not answered.done():
                answered.set_result(index)

        probes: set[asyncio.Task[None]] = set()
        try:
            while not answered.done():
                probes = {task for task in probes if not task.done()}
                probes |= {asyncio.create_task(probe(i)) for i in range(len(hops))}
                if once:
                    pending = set(probes)
                    while pending and not answered.done():
                        _, pending = await asyncio.wait(pending, return_when=FIRST_COMPLETED)
                    break
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(asyncio.shield(answered), PROBE_EVERY)
            return answered.result() if answered.done() else None
        finally:
            for task in probes:
                task.cancel()
            await asyncio.gather(*probes, return_exceptions=True)

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
            ping_interval=None,  # our own keepalive: lenient while a standby holds the Hello
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
                first = decode_lab(await self._first_answer(ws))
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
            self._answers.clear()
            self.host.link_back()
            self.connected.set()
            log.info("linked to %s as rig %s", url, s.rig)
            tasks = [
                asyncio.create_task(self._send(ws)),
                asyncio.create_task(self._beat(ws)),
                asyncio.create_task(self._receive(ws)),
                asyncio.create_task(self._keepalive(ws, s.ping_timeout)),
            ]
            try:
                done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
                for task in done:
                    task.result()  # raise what ended the session
            finally:
                for task in tasks:
                    task.cancel()
                await asyncio.gather(*tasks, return_exceptions=True)

    async def _first_answer(self, ws: ClientConnection) -> str | bytes:
        """The lab's answer to the Hello: ``Welcome``, or a close (raised).

        A standby may hold the Hello through a takeover (``HELLO_HOLD``), and
        it is busiest then — opening the rigs, adopting the runs — so its pongs
        may come late: the pings meanwhile wait :data:`HELLO_PING_TIMEOUT`, not
        ``ping_timeout``, or the host would drop the very link that keeps its run
        (a dead worker's connection closes by itself; a hung one is told in time).
        """
        answer = asyncio.create_task(asyncio.wait_for(ws.recv(), HELLO_HOLD + 10))
        alive = asyncio.create_task(self._keepalive(ws, HELLO_PING_TIMEOUT))
        try:
            done, _ = await asyncio.wait({answer, alive}, return_when=FIRST_COMPLETED)
            if alive in done:
                alive.result()  # raise why the worker is taken for dead
            return answer.result()
        finally:
            for task in (answer, alive):
                task.cancel()
            await asyncio.gather(answer, alive, return_exceptions=True)

    async def _keepalive(self, ws: ClientConnection, timeout: float) -> None:
        """Ping every ``ping`` seconds; raise :class:`TimeoutError` if a pong takes ``timeout``.

        The ``websockets`` client's own keepalive, with a timeout that depends on
        the link's phase (:meth:`_first_answer`).
        """
        while True:
            await asyncio.sleep(self.settings.ping)
            pong = await ws.ping()
            try:
                await asyncio.wait_for(pong, timeout)
            except TimeoutError:
                raise TimeoutError(f"no answer to a ping for {timeout:g} s") from None

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
                elif isinstance(message, SetChannel):
                    await asyncio.to_thread(
                        self.host.set_channel, message.name, message.level, message.run
                    )
                elif isinstance(message, SetMode | SetSetpoint | SetGains | SetFan):
                    await asyncio.to_thread(self.host.command, message)
            except ThermoLabError as exc:
                log.warning("%s refused: %s", message.type, exc)


def _first_hop(url: str) -> tuple[str, int]:
    """Where a dial of ``url`` opens its TCP connection: the lab, or the proxy to it."""
    uri = parse_uri(url)
    proxy = get_proxy(uri)
    if proxy is None:
        return uri.host, uri.port
    hop = parse_proxy(proxy)
    return hop.host, hop.port


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
