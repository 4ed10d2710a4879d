"""The live WebSocket ``/api/rigs/{rig}/live`` (contract: ``docs/live-protocol.md``).

:class:`LiveEndpoint` listens to the lab (access changes, runs, runner
events, idle readings), turns what it hears into the protocol's messages on
each rig's :class:`~thermolab.lab.live.fanout.LiveChannel`, and serves the clients:
``hello``, the replay of what a reconnecting client missed (from memory, or
the current run's samples from the store when memory no longer has them;
:mod:`~thermolab.lab.http.live_replay`, paged and budgeted), then the live
messages. Sockets are limited per login and per rig (the lab's access
policy; lab-wide over a fleet's workers, :mod:`~thermolab.lab.fleet.shared_limits`).
A client's ``ping`` keeps its control or queue place alive and is answered
with ``pong``.

A connection lives as long as the login (or API token) it was opened with
(:class:`~thermolab.lab.http.live_logins.LoginWatch`). A script connects with
a personal API token (``Authorization: Bearer`` on the handshake,
:mod:`~thermolab.lab.http.credentials`).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Mapping
from datetime import datetime, timedelta
from typing import Annotated, Any, Literal, TypeVar

import anyio
import anyio.to_thread
from fastapi import Query
from starlette.websockets import WebSocket, WebSocketDisconnect

from thermolab.jsonsafe import finite_or_none
from thermolab.lab.access import RigSnapshot
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.models import Role
from thermolab.lab.fleet.shared_limits import LiveSocketCounts
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.http.live_hello import HelloReader
from thermolab.lab.http.live_logins import KnownLogins, LoginWatch
from thermolab.lab.http.live_messages import (
    AccessMessage,
    EstimateMessage,
    RunMessage,
    SampleMessage,
    StateMessage,
)
from thermolab.lab.http.live_replay import ReplayBudget, ReplayTooSlowError, replay
from thermolab.lab.http.live_serve import serve_client
from thermolab.lab.http.routers.runs import RunOut
from thermolab.lab.http.schemas import RigOut, people_named
from thermolab.lab.live.fanout import (
    CLOSE_RIG_FULL,
    CLOSE_TOO_MANY,
    CLOSE_TOO_SLOW,
    CLOSE_UNAUTHORIZED,
    CLOSE_UNKNOWN_RIG,
    MAX_SEQ,
    Batch,
    LiveChannel,
    LiveClient,
    LiveFanout,
    encode,
)
from thermolab.lab.live.turnstile import take_turn
from thermolab.lab.runs import RunRecord
from thermolab.lab.service import Lab
from thermolab.runner import EstimateEvent, Event, SampleEvent

__all__ = ["LiveEndpoint"]

log = logging.getLogger(__name__)
_T = TypeVar("_T")

_PING_INTERVAL = timedelta(seconds=1)  # pings look at the rig at most this often
_LIVE_THREADS = 4  # worker threads live sockets may hold at once (requests keep the rest)


def _dump(model: RigOut | RunOut) -> dict[str, Any]:
    return model.model_dump(mode="json", by_alias=True)


class LiveEndpoint:
    """The lab's live stream: a :class:`~thermolab.lab.listener.LabListener` and the endpoint.

    Parameters
    ----------
    lab : Lab
    access_delay : float
        Seconds over which access changes are gathered into one ``access``
        message per client.
    client_queue : int
        Messages a client may have waiting before it is cut as too slow.
    session_check : float or None
        Seconds between checks that every client's login still exists, for
        logins ended by another process (``thermolab user remove``); logins
        this lab ends arrive at once as :attr:`Lab.logins_ended` events. Whom a
        login belongs to is remembered as long (``None``: never), so that a
        storm of joins reads each login once (:class:`KnownLogins`).
    budget : ReplayBudget, optional
        How replays share the server (default: :class:`ReplayBudget`'s).
    sockets : LiveSocketCounts, optional
        The sockets held, per login and per rig: this worker's alone (the
        default), or every live worker's of a fleet
        (:class:`~thermolab.lab.fleet.shared_limits.SharedLiveSocketCounts`).

    The socket limits (per login, per rig) and the most stored samples one
    socket is replayed come from the lab's :class:`~thermolab.lab.config.AccessPolicy`.
    """

    def __init__(
        self,
        lab: Lab,
        *,
        access_delay: float = 0.2,
        client_queue: int = 2000,
        session_check: float | None = 5.0,
        budget: ReplayBudget | None = None,
        sockets: LiveSocketCounts | None = None,
    ) -> None:
        self.lab = lab
        policy = lab.config.access
        self._sockets_per_login = policy.live_sockets_per_login
        self._sockets_per_rig = policy.live_sockets_per_rig
        self._replay_limit = policy.live_replay_samples
        self.budget = budget if budget is not None else ReplayBudget()
        self.sockets = sockets if sockets is not None else LiveSocketCounts()
        self.hub = LiveFanout([rig.id for rig in lab.config.rigs])
        self._access_delay = access_delay
        self._client_queue = client_queue
        self._session_check = session_check
        self._states: dict[str, tuple[str, str | None]] = {}
        self._signatures: dict[str, tuple[Any, ...]] = {}
        self._holders: dict[str, frozenset[int | None]] = {}  # who holds a control or queue place
        # When each (rig, user) holding a place last had it kept by a ping: one heartbeat a
        # second per user, however many of their sockets ping (tabs, a projector).
        self._kept_at: dict[tuple[str, int | None], datetime] = {}
        self._limiter: anyio.CapacityLimiter | None = None
        # Whom a socket's login is, remembered as long as an ended login may go unnoticed
        # anyway (the periodic session check): a join storm reads each login once.
        self.known = KnownLogins(lab, session_check or 0.0, self._in_thread)
        self.logins = LoginWatch(lab, self.hub, self.known)
        self._hellos = HelloReader(lab, self._in_thread)
        # Watchers arriving or leaving on other workers change the count everyone sees.
        lab.presence.on_elsewhere(self.access_changed)

    # -- the lab's side (worker threads) ---------------------------------------------------

    def access_changed(self, rig_id: str) -> None:
        """Schedule one ``access`` (and ``state``) update of every client of the rig."""
        self.hub.access_changed(rig_id, self._refresh, self._access_delay)

    def run_changed(self, rig_id: str, event: str, record: RunRecord) -> None:
        """Publish ``run`` (started / ended)."""
        kind: Literal["started", "ended"] = "started" if event == "started" else "ended"
        message: RunMessage = {"type": "run", "event": kind, "run": _dump(RunOut.of(record))}
        self.hub.publish(rig_id, message)

    def run_event(self, rig_id: str, run_id: int, event: Event) -> None:
        """Publish a run's samples and estimates."""
        if isinstance(event, SampleEvent):
            sample: SampleMessage = {
                "type": "sample",
                "run": run_id,
                "k": event.k,
                "t": event.t,
                "u": event.u,
                "y": event.y,
                "channels": {n: finite_or_none(v) for n, v in event.channels().items()},
            }
            self.hub.publish(rig_id, sample)
        elif isinstance(event, EstimateEvent):
            estimate = event.estimate.to_dict()
            message: EstimateMessage = {
                "type": "estimate",
                "run": run_id,
                "method": event.method,
                "k": event.k,
                "K": estimate.get("K"),
                "tau": estimate.get("tau"),
                "W": estimate.get("W"),
                "valid": estimate.get("valid"),
                "final": event.final,
                # Why there is no model (not excited yet, unstable a, ...), else null.
                "reason": (estimate.get("extras") or {}).get("reason"),
            }
            self.hub.publish(rig_id, message)

    def reading(
        self,
        rig_id: str,
        u: float | None,
        y: float,
        at: datetime,
        channels: Mapping[str, float | None] | None = None,
    ) -> None:
        """Publish an idle-monitoring sample (no run: ``run`` and ``k`` are null).

        Its channels are ``t``, ``u``, ``y`` and the rig's further ones (a kit's ``t2``, ``q2``).
        """
        further = {n: None if v is None else finite_or_none(v) for n, v in (channels or {}).items()}
        sample: SampleMessage = {
            "type": "sample",
            "run": None,
            "k": None,
            "t": at.timestamp(),
            "u": u,
            "y": y,
            "channels": {"t": at.timestamp(), "u": u, "y": y, **further},
        }
        self.hub.publish(rig_id, sample)

    # -- the event loop's side --------------------------------------------------------------

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Serve clients on ``loop`` (``None`` when the server stops; call in the loop)."""
        self.hub.bind(loop)
        self.budget.bind()
        self.logins.bind(loop, self._session_check)

    def _refresh(self, rig_id: str) -> None:
        task = asyncio.ensure_future(self._push_access(rig_id))
        task.add_done_callback(_log_failure)

    async def _push_access(self, rig_id: str) -> None:
        channel = self.hub.channels[rig_id]
        snap = await self._in_thread(self.lab.access.snapshot, rig_id)
        holders = self._holders[rig_id] = _holders(snap)
        for key in [k for k in self._kept_at if k[0] == rig_id and k[1] not in holders]:
            del self._kept_at[key]  # their place is gone: nothing left to keep
        watchers = self.lab.presence.watchers(rig_id)
        # Heartbeats change nothing anyone sees: only a visible change is sent.
        signature = _signature(snap, len(watchers))
        if self._signatures.get(rig_id) == signature:
            return
        self._signatures[rig_id] = signature
        clients = channel.clients()

        def render() -> tuple[tuple[str, str | None], dict[Any, str]]:
            # Every plain watcher sees the same access; the controller and each queued
            # user their own. One rendering per viewpoint, however many clients.
            system = self.lab.access.render(snap, _NOBODY, watchers)
            texts: dict[Any, str] = {}
            for client in clients:
                key = _viewpoint(snap, client.key)
                if key not in texts:
                    view = self.lab.access.render(snap, client.key, watchers)
                    named = self.lab.names.names(people_named(view))
                    access = _dump(RigOut.of(view, named))["access"]
                    message: AccessMessage = {"type": "access", "access": access}
                    texts[key] = encode(message)
            return (system.state, system.fault), texts

        state, texts = await self._in_thread(render)
        if self._states.get(rig_id) != state:
            self._states[rig_id] = state
            changed: StateMessage = {"type": "state", "state": state[0], "detail": state[1]}
            channel.publish(changed)
        batches = {key: Batch.of([text]) for key, text in texts.items()}  # one frame each
        for client in clients:
            client.offer_batch(batches[_viewpoint(snap, client.key)])

    async def endpoint(
        self,
        websocket: WebSocket,
        rig_id: str,
        since: Annotated[int | None, Query(ge=0, le=MAX_SEQ)] = None,
    ) -> None:
        """Serve one client (the WebSocket route)."""
        await websocket.accept()
        cookie = websocket.cookies.get(COOKIE_NAME)
        authorization = websocket.headers.get("authorization")
        who = await self.known.resolve(cookie, authorization)
        # Every joiner that waited for one reading of its login wakes in the same turn:
        # they go on a few per turn, as they came in.
        await take_turn()
        if who is None:
            await websocket.close(CLOSE_UNAUTHORIZED, "not logged in")
            return
        channel = self.hub.channels.get(rig_id)
        if channel is None:
            await websocket.close(CLOSE_UNKNOWN_RIG, f"no rig called {rig_id!r}")
            return
        # One login cannot hold the server's sockets (and replays) for everyone, nor one
        # rig's watchers every connection the server accepts. Other workers' sockets are
        # read first; this worker's, exact, are read and counted with no await between.
        login = who.login_key
        others = self.sockets.others
        elsewhere = await self._in_thread(others, login, rig_id) if self.sockets.shared else (0, 0)
        here = self.sockets.here(login, rig_id)
        if here[0] + elsewhere[0] >= self._sockets_per_login:
            await websocket.close(
                CLOSE_TOO_MANY,
                f"at most {self._sockets_per_login} live sockets per login; close one first",
            )
            return
        if here[1] + elsewhere[1] >= self._sockets_per_rig:
            await websocket.close(
                CLOSE_RIG_FULL,
                f"rig {rig_id!r} has its {self._sockets_per_rig} live sockets; try again later",
            )
            return
        self.sockets.add(login, rig_id)
        try:
            await self._attached(websocket, channel, rig_id, who, since)
        finally:
            self.sockets.remove(login, rig_id)

    async def _attached(
        self,
        websocket: WebSocket,
        channel: LiveChannel,
        rig_id: str,
        who: Principal,
        since: int | None,
    ) -> None:
        client = LiveClient(key=who, maxsize=self._client_queue)
        presence = self.lab.presence.connect(rig_id, who.username)
        start = channel.attach(client)
        gone = False

        def leave() -> None:  # once, as soon as the client is cut or gone
            nonlocal gone
            if not gone:
                gone = True
                channel.detach(client)
                self.lab.presence.disconnect(presence)
                self.access_changed(rig_id)

        try:
            await self._hello(websocket, rig_id, who, start)
            if since is not None and since != start:
                try:
                    await replay(
                        websocket,
                        channel,
                        self.lab.runs.stored_samples,
                        self.lab.running(rig_id),
                        since,
                        start,
                        user_id=who.user_id,
                        budget=self.budget,
                        limit=self._replay_limit,
                    )
                except ReplayTooSlowError:
                    client.close(CLOSE_TOO_SLOW, "too slow: reconnect with since")
            self.access_changed(rig_id)  # one more watcher
            await serve_client(websocket, client, lambda: self._ping(rig_id, who, client), leave)
        except WebSocketDisconnect:
            pass
        finally:
            leave()

    async def _hello(self, websocket: WebSocket, rig_id: str, who: Principal, seq: int) -> None:
        # Read with every other client joining meanwhile (a class at the bell), and sent
        # a few clients per turn of the loop: a batch of a thousand hellos, sent at once,
        # would hold the loop (and the samples due meanwhile) for all of them.
        text = await self._hellos.hello(rig_id, who, seq)
        await take_turn()
        await websocket.send_text(text)

    async def _ping(self, rig_id: str, who: Principal, client: LiveClient) -> None:
        # A ping is the client being here: presence (memory, in the loop) and, for whoever
        # holds a control or queue place, the heartbeat that keeps it (at most once a second).
        now = self.lab.clock.now()
        if client.last_ping is not None and now - client.last_ping < _PING_INTERVAL:
            return
        client.last_ping = now
        self.lab.presence.touch(rig_id, who.username)
        holders = self._holders.get(rig_id)
        if holders is None or who.user_id in holders:
            # The place is the user's, not the socket's: one heartbeat a second however
            # many of their sockets ping. Per socket, a user with many sockets would queue
            # store work without bound, and every waiting socket's reads stop (uvicorn
            # reads a socket's next frame once the app took the last one), so the server's
            # own keepalive pongs go unread and the connections are failed (1011).
            key = (rig_id, who.user_id)
            kept = self._kept_at.get(key)
            if kept is not None and now - kept < _PING_INTERVAL:
                return
            self._kept_at[key] = now
            await self._in_thread(self.lab.access.view, rig_id, who)

    async def _in_thread(self, work: Callable[..., _T], *args: Any) -> _T:
        # Live sockets' store work shares a few threads: watchers never queue requests.
        if self._limiter is None:
            self._limiter = anyio.CapacityLimiter(_LIVE_THREADS)
        return await anyio.to_thread.run_sync(work, *args, limiter=self._limiter)


def _signature(snap: RigSnapshot, watchers: int) -> tuple[Any, ...]:
    """What watchers can see of a rig's access state (not heartbeats, not the clock)."""
    control = snap.controller
    return (
        None if control is None else (control.id, control.deadline),
        tuple(slot.user_id for slot in snap.queue),
        snap.power,
        snap.fault,
        snap.in_service,
        snap.run_active,
        watchers,
    )


def _holders(snap: RigSnapshot) -> frozenset[int | None]:
    """The users whose pings keep a place (control, the queue) in the store."""
    holders: set[int | None] = {slot.user_id for slot in snap.queue}
    if snap.controller is not None:
        holders.add(snap.controller.user_id)
    return frozenset(holders)


def _viewpoint(snap: RigSnapshot, who: Principal) -> Any:
    """Clients that see the same access message share a viewpoint."""
    if snap.controller is not None and snap.controller.user_id == who.user_id:
        return ("controller", who.user_id)
    if snap.slot_of(who.user_id) is not None:
        return ("queued", who.user_id)
    return "watcher"


def _log_failure(task: asyncio.Future[None]) -> None:
    if not task.cancelled() and task.exception() is not None:
        log.error("live access update failed", exc_info=task.exception())


# Renders a rig for nobody in particular (state, and the lab's own replays): a teacher's view.
_NOBODY = Principal(user_id=-1, username="(live)", role=Role.TEACHER)
