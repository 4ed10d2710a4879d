"""The lab's end of its rig hosts' links: who is online, what they send, what they are told.

:class:`AgentHub` serves the WebSocket ``/api/agents/link``
(:data:`~thermolab.agent.protocol.AGENT_LINK_PATH`) that ``thermolab agent``
dials. A host proves it is its rig's with the secret the lab issued
(:mod:`.secrets`); one host serves a rig: a second host process is refused
while the first is linked and talking, the same process redialling replaces
its old link, and a rotated secret drops the link made with the old one.

Samples are stored idempotently (``INSERT ... ON CONFLICT DO NOTHING`` on
the samples' key ``(run_id, k)``) and acknowledged by their ``seq`` only
once committed, so a backlog sent again after a link loss, or an Ack lost
with the link, never stores a sample twice nor loses one.

Health (the monitor, :meth:`AgentHub.check`, once a sweep) is judged by
:mod:`.health`; the hub puts its faults on the rigs and clears them.

**One rule for a lost link**: the ``grace`` the lab gives a host (sent in
``Welcome``) is both how long the host's run outlives a lost link and how
long the lab keeps the rig in service — and so the controller's turn —
while the host is away, counted from the last message heard. A link loss
inside the grace thus keeps the turn and the run; a longer one ends both,
the run's end naming the lost link (the host's ``RunEnded`` says so). A
link silent for :data:`LINK_SILENCE` is dropped (the host is shown offline
at once and redials), which is not yet out of service.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from datetime import datetime, timedelta
from typing import Any

from fastapi import WebSocket, WebSocketDisconnect
from pydantic import ValidationError
from sqlalchemy import select, update

from thermolab.agent.protocol import (
    CLOSE_REFUSED,
    PROTOCOL_VERSION,
    Ack,
    EndRun,
    Heartbeat,
    Hello,
    LoopCommand,
    Power,
    RunEnded,
    SampleBatch,
    SetChannel,
    SetInput,
    StartRun,
    Welcome,
    decode_agent,
    encode,
)
from thermolab.lab.access import AccessService
from thermolab.lab.agents.health import HEALTH_FAULT, HostStatus, host_problem
from thermolab.lab.agents.samples import store_samples
from thermolab.lab.agents.secrets import check_secret
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.agent_models import AgentHost
from thermolab.lab.rigs.devices import DeviceHub

__all__ = ["AgentHub"]

log = logging.getLogger(__name__)

LINK_SILENCE = 5.0
"""Seconds without a message (a host beats every second) after which its link is dropped.

The host is offline from then on (it redials); its rig stays in service
until it has been away for the grace.
"""

DEFAULT_GRACE = 30.0
"""Seconds a host may be away before its run ends and its rig goes out of service.

Above a takeover's longest gap (the lease's 15 s and two announcements), so
that a run on a rig host outlives its owner's death on another machine.
"""


@dataclass
class _Link:
    ws: WebSocket
    loop: asyncio.AbstractEventLoop
    status: HostStatus
    host: str = ""  # Hello.host: which host process (empty from hosts before it)
    secret: str = ""  # the secret it proved, checked again at every sweep (rotation)
    closed: asyncio.Event = field(default_factory=asyncio.Event)


class AgentHub:
    """The rig hosts of the lab's remote rigs (``agent = true`` in its file).

    Parameters
    ----------
    db, clock, config, access, devices
        The lab's.
    on_online : callable
        Called (in a worker thread) with a rig id when its host comes or goes.
    grace : float
        Seconds a host may be away — its run outlives a lost link on the host
        (sent in ``Welcome``), and its rig stays in service, the turn with it.
    notify : callable, optional
        Told ``(rig_id, what)`` when a rig goes out of service or comes back.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        config: LabConfig,
        access: AccessService,
        devices: DeviceHub,
        *,
        on_online: Callable[[str], None],
        grace: float = DEFAULT_GRACE,
        notify: Callable[[str, str], None] | None = None,
    ) -> None:
        self._db = db
        self._clock = clock
        self._config = config
        self._access = access
        self._devices = devices
        self._on_online = on_online
        self.grace = grace
        #: Told ``(rig_id, what)`` when a rig goes out of service or back (e-mail: :mod:`.notify`).
        self.notify = notify
        self._lock = threading.Lock()
        self._links: dict[str, _Link] = {}
        self._status = {r.id: HostStatus(r.id) for r in config.rigs if r.agent}
        #: Each host's last told ``(run, control loop)`` (its heartbeat's).
        self._loops: dict[str, tuple[int | None, dict[str, Any] | None]] = {}
        # The safe range a host's readings must stay in: the rig kind's output limit.
        self._limits = {r.id: r.rig_spec.describe().output_limit for r in config.rigs if r.agent}
        #: Called with ``(rig_id, samples)`` after samples are stored, and ``(rig_id, RunEnded)``.
        self.on_samples: Callable[[str, SampleBatch], None] = lambda rig, batch: None
        self.on_run_ended: Callable[[str, RunEnded], None] = lambda rig, ended: None
        self._expected_until: datetime | None = None

    def expect_hosts(self, until: datetime) -> None:
        """Give hosts not linked yet until ``until`` to dial in before their rigs are faulted.

        A standby that just took the rigs over (docs/fleet.md, "Takeover"): the
        hosts were linked to the dead owner and are dialling their next
        address; a run on one goes on there through the same grace.
        """
        self._expected_until = until

    def serves(self, rig_id: str) -> bool:
        """Whether ``rig_id`` is a remote rig."""
        return rig_id in self._status

    def online(self, rig_id: str) -> bool:
        """Whether the rig's host is connected now."""
        with self._lock:
            return rig_id in self._links

    def statuses(self) -> list[HostStatus]:
        """Every rig host, online or not (the status page)."""
        with self._db.read() as session:
            rows = {r.rig_id: r for r in session.scalars(select(AgentHost))}
        out = []
        for rig_id, status in self._status.items():
            row = rows.get(rig_id)
            if row is not None and status.last_contact is None:
                status.last_contact, status.version = row.last_contact, row.version
                status.spec = row.spec
            # The rig's fault as the lab holds it (the monitor's or any other), not only the host's.
            out.append(replace(status, fault=self._access.snapshot(rig_id).fault or status.fault))
        return out

    def loop(self, rig_id: str, run_id: int) -> dict[str, Any] | None:
        """Run ``run_id``'s control loop as the host's last heartbeat told it, if any."""
        run, loop = self._loops.get(rig_id, (None, None))
        return loop if run == run_id else None

    def send(
        self, rig_id: str, message: StartRun | EndRun | SetInput | Power | LoopCommand
    ) -> bool:
        """Send a command to the rig's host (from any thread); ``False`` if it is not connected."""
        with self._lock:
            link = self._links.get(rig_id)
        if link is None:
            return False
        text = encode(message)
        link.loop.call_soon_threadsafe(lambda: link.loop.create_task(_send(link, text)))
        return True

    def sync_power(self, rig_id: str, *, hand_over: bool = False) -> None:
        """Tell the host the power the device hub holds for the rig.

        ``hand_over``: the turn changed, so the host rests its rig first (powered
        off: every actuator at its declared default, as ``DeviceHub`` does
        in-process) and powers it again at its safe input. The idle input is
        never re-sent from here: the hub knows it from the host's heartbeats,
        and a heartbeat of the last turn arriving after a hand-over would give
        the next controller the last one's heater (issue #23).
        """
        if not self.serves(rig_id):
            return
        powered = self._devices.powered(rig_id)
        if hand_over:
            self.send(rig_id, Power(on=False))
        self.send(rig_id, Power(on=powered))

    def apply(self, rig_id: str, u: float) -> bool:
        """Send a controller's input to the idle powered remote rig; whether it was sent."""
        return (
            self.serves(rig_id)
            and self._devices.powered(rig_id)
            and self.send(rig_id, SetInput(u=u))
        )

    def set_channel(self, rig_id: str, name: str, level: float) -> bool:
        """Send a controller's further input level to the idle powered remote rig; whether sent."""
        return (
            self.serves(rig_id)
            and self._devices.powered(rig_id)
            and self.send(rig_id, SetChannel(name=name, level=level))
        )

    # -- the monitor ---------------------------------------------------------------------

    def _another_host(self, old: _Link, host: str) -> bool:
        """Whether a hello from ``host`` comes from a second host while ``old`` serves.

        The same process redialling (its old link half-open after a blip) replaces
        its link; so does anyone once the old link has been silent past the timeout,
        and a host that does not say who it is (an older version).
        """
        if not (old.host and host) or old.host == host:
            return False
        heard = old.status.last_contact
        return heard is not None and self._clock.now() - heard <= timedelta(seconds=LINK_SILENCE)

    def check(self, now: datetime) -> None:
        """Judge every host's health; fault or heal its rig (called by the lab's sweep).

        A link whose secret was rotated since it dialled in (``thermolab agent
        secret``) is dropped here: the host must dial again with the new one.
        """
        with self._lock:
            links = list(self._links.items())
        for rig_id, linked in links:
            if linked.secret and not check_secret(self._db, rig_id, linked.secret):
                log.warning("rig host %s: its secret was rotated; its link is dropped", rig_id)
                linked.loop.call_soon_threadsafe(linked.closed.set)
        for rig_id, status in self._status.items():
            with self._lock:
                online = rig_id in self._links
            problem = host_problem(
                status,
                now,
                linked=online,
                grace=self.grace,
                limit=self._limits[rig_id],
                expected_until=self._expected_until,
            )
            if problem is None:
                if self._access.clear_healed_fault(rig_id, HEALTH_FAULT) and self.notify:
                    self.notify(rig_id, "back in service (its host is healthy)")
                continue
            fault = self._access.snapshot(rig_id).fault
            if fault is None:
                self._access.report_fault(rig_id, HEALTH_FAULT + problem)
                if self.notify is not None:
                    self.notify(rig_id, "out of service: " + problem)
        for rig_id, linked in links:  # after the faults are stored, which name the silence
            heard = linked.status.last_contact
            if heard is not None and now - heard > timedelta(seconds=LINK_SILENCE):
                # Gone quiet (a cut cable): offline now, out of service only after the grace.
                log.warning("rig host %s: silent for over %g s; link dropped", rig_id, LINK_SILENCE)
                linked.loop.call_soon_threadsafe(linked.closed.set)

    # -- the WebSocket ---------------------------------------------------------------------

    async def endpoint(
        self, ws: WebSocket, *, accepted: bool = False, hello: str | None = None
    ) -> None:
        """Serve one rig host's connection until it closes (``accepted``: already, by a
        hold, which read its first message, ``hello``)."""
        if not accepted:
            await ws.accept()
        try:
            said = hello if hello is not None else await asyncio.wait_for(ws.receive_text(), 10)
            first = decode_agent(said)
        except (ValidationError, TimeoutError, WebSocketDisconnect):
            await _close(ws, "expected hello")
            return
        if not isinstance(first, Hello) or not await asyncio.to_thread(self._admit, first):
            await _close(ws, "unknown rig, wrong secret or protocol version")
            return
        rig_id = first.rig
        status = self._status[rig_id]
        link = _Link(ws, asyncio.get_running_loop(), status, first.host, first.secret)
        with self._lock:
            old = self._links.get(rig_id)
            other = old is not None and self._another_host(old, first.host)
            if not other:
                self._links[rig_id] = link
        if other:
            assert old is not None
            machine = old.host.split(":")[0]
            log.warning(
                "rig host %s: refused a second host (%s) while %s serves it",
                rig_id,
                first.host,
                old.host,
            )
            await _close(
                ws,
                f"rig {rig_id!r} is served by another host ({machine}): one host per rig; "
                "stop that one first",
            )
            return
        if old is not None:
            old.closed.set()
        status.online, status.version, status.spec = True, first.version, first.spec
        self._devices.host_said(rig_id, first.speedup)
        status.last_contact, status.fault = self._clock.now(), None
        receiver: asyncio.Task[None] | None = None
        closer: asyncio.Task[bool] | None = None
        try:  # from the registration on: whatever ends the socket, the rig goes offline
            await ws.send_text(encode(Welcome(grace=self.grace)))
            await asyncio.to_thread(self._came, rig_id, first)
            receiver = asyncio.create_task(self._receive(rig_id, link))
            closer = asyncio.create_task(link.closed.wait())
            await asyncio.wait({receiver, closer}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in (receiver, closer):
                if task is not None:
                    task.cancel()
            if receiver is not None and receiver.done() and not receiver.cancelled():
                failure = receiver.exception()
                if failure is not None:
                    log.error("rig host %s: link failed", rig_id, exc_info=failure)
            with self._lock:
                mine = self._links.get(rig_id) is link
                if mine:
                    del self._links[rig_id]
            if mine:
                status.online = False
                # A thread of its own: this task may be being cancelled (server shutdown).
                threading.Thread(target=self._gone, args=(rig_id,), daemon=True).start()
            await _close(ws, "replaced or silent", code=1001)

    async def _receive(self, rig_id: str, link: _Link) -> None:
        status = link.status
        while True:
            try:
                message = decode_agent(await link.ws.receive_text())
            except ValidationError as exc:
                log.warning("rig host %s sent a bad message: %s", rig_id, exc.errors()[:1])
                return
            except (WebSocketDisconnect, RuntimeError) as exc:
                log.info("rig host %s: link closed (%r)", rig_id, exc)
                return
            status.last_contact = self._clock.now()
            try:
                await self._handle(rig_id, link, message)
            except WebSocketDisconnect:
                log.info("rig host %s: link closed while answering", rig_id)
                return

    async def _handle(
        self, rig_id: str, link: _Link, message: Hello | Heartbeat | SampleBatch | RunEnded
    ) -> None:
        """One message of the host: a heartbeat noted, samples or a run's end stored and acked."""
        status = link.status
        if isinstance(message, Heartbeat):
            status.powered, status.u, status.y = message.powered, message.u, message.y
            status.fault, status.pending = message.fault, message.pending
            self._loops[rig_id] = (message.run, message.loop)
            if message.y is not None and message.run is None and math.isfinite(message.y):
                self._devices.note_sample(rig_id, message.u or 0.0, message.y)
        elif isinstance(message, SampleBatch) and message.samples:
            await asyncio.to_thread(self._store, rig_id, message)
            try:  # the live stream's business: stored is stored, the Ack goes out
                # A thread: the identifiers run there (in order: awaited before the next).
                await asyncio.to_thread(self.on_samples, rig_id, message)
            except Exception:
                log.exception("rig host %s: telling the samples failed", rig_id)
            await link.ws.send_text(encode(Ack(seq=message.samples[-1].seq)))
        elif isinstance(message, RunEnded):
            await asyncio.to_thread(self.on_run_ended, rig_id, message)
            await link.ws.send_text(encode(Ack(seq=message.seq)))

    # -- in worker threads -------------------------------------------------------------------

    def _admit(self, hello: Hello) -> bool:
        return (
            hello.protocol == PROTOCOL_VERSION
            and self.serves(hello.rig)
            and check_secret(self._db, hello.rig, hello.secret)
        )

    def _came(self, rig_id: str, hello: Hello) -> None:
        with self._db.write() as session:
            row = session.get(AgentHost, rig_id)
            if row is not None:
                row.last_contact, row.version, row.spec = (
                    self._clock.now(),
                    hello.version,
                    hello.spec,
                )
        log.info("rig host %s online (%s, %s)", rig_id, hello.version, hello.spec)
        self.check(self._clock.now())
        self._on_online(rig_id)

    def _gone(self, rig_id: str) -> None:
        log.warning("rig host %s offline", rig_id)
        try:
            self._mark_gone(rig_id)
        except Exception:
            log.exception("rig host %s: could not record it offline", rig_id)

    def _mark_gone(self, rig_id: str) -> None:
        with self._db.write() as session:
            session.execute(
                update(AgentHost)
                .where(AgentHost.rig_id == rig_id)
                .values(last_contact=self._status[rig_id].last_contact)
            )
        self.check(self._clock.now())
        self._on_online(rig_id)

    def _store(self, rig_id: str, batch: SampleBatch) -> None:
        store_samples(self._db, rig_id, batch)


async def _send(link: _Link, text: str) -> None:
    try:
        await link.ws.send_text(text)
    except Exception as exc:
        log.info("rig host %s: cannot send (%r)", link.status.rig, exc)
        link.closed.set()


async def _close(ws: WebSocket, reason: str, code: int = CLOSE_REFUSED) -> None:
    with contextlib.suppress(RuntimeError, OSError, WebSocketDisconnect):  # closed already
        await ws.close(code=code, reason=reason)
