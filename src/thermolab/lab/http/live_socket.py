"""The live WebSocket ``/api/rigs/{rig}/live`` (contract: ``docs/live-protocol.md``).

:class:`LiveEndpoint` listens to the lab (access changes, runs, runner
events, idle readings), turns what it hears into the protocol's messages on
each rig's :class:`~thermolab.lab.fanout.LiveChannel`, and serves the clients:
``hello``, the replay of what a reconnecting client missed (from memory, or
the current run's samples from the store when memory no longer has them;
:mod:`~thermolab.lab.http.live_replay`, paged and budgeted), then the live
messages. Sockets are limited per login and per rig (the lab's access
policy). A client's ``ping`` keeps its control or queue place alive and is
answered with ``pong``.

A connection lives as long as the login it was opened with: the lab
announces every login it ends (logout, expiry, a password change, an account
removed) as a :class:`~thermolab.lab.users.LoginsEnded` event, and those
clients are closed with 4401 at once; a check every few seconds catches
logins ended by another process (an account removed from the command line).
A script connects with a personal API token (``Authorization: Bearer`` on
the handshake, :mod:`~thermolab.lab.http.credentials`); revoking the token
closes its connections the same way (:attr:`Lab.tokens` ``.revoked``).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import logging
from collections.abc import Callable, Collection
from datetime import datetime, timedelta
from typing import Annotated, Any, Literal

import anyio.to_thread
from fastapi import Query
from sqlalchemy import select
from starlette.websockets import WebSocket, WebSocketDisconnect, WebSocketState

from thermolab.jsonsafe import finite_or_none
from thermolab.lab.access import RigSnapshot
from thermolab.lab.db.models import LoginSession, Role
from thermolab.lab.fanout import (
    CLOSE_RIG_FULL,
    CLOSE_TOO_MANY,
    CLOSE_TOO_SLOW,
    CLOSE_UNAUTHORIZED,
    CLOSE_UNKNOWN_RIG,
    MAX_SEQ,
    LiveChannel,
    LiveClient,
    LiveFanout,
    encode,
)
from thermolab.lab.http.credentials import resolve_principal
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.http.live_messages import (
    AccessMessage,
    ErrorMessage,
    EstimateMessage,
    HelloMessage,
    RunMessage,
    SampleMessage,
    StateMessage,
    client_message_type,
)
from thermolab.lab.http.live_replay import ReplayBudget, ReplayTooSlowError, replay
from thermolab.lab.http.schemas import RigOut, RunOut
from thermolab.lab.runs import RunRecord
from thermolab.lab.service import Lab
from thermolab.lab.users import Principal
from thermolab.runner import EstimateEvent, Event, SampleEvent

__all__ = ["LiveEndpoint"]

log = logging.getLogger(__name__)

_PING_INTERVAL = timedelta(seconds=1)  # pings look at the rig at most this often
_CLOSE_TIMEOUT = 10.0  # seconds a close frame may wait for a stalled socket to drain


def _dump(model: RigOut | RunOut) -> dict[str, Any]:
    return model.model_dump(mode="json", by_alias=True)


class LiveEndpoint:
    """The lab's live stream: a :class:`~thermolab.lab.service.LabListener` and the endpoint.

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
        this lab ends arrive at once as :attr:`Lab.logins_ended` events.
    budget : ReplayBudget, optional
        How replays share the server (default: :class:`ReplayBudget`'s).

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
    ) -> None:
        self.lab = lab
        policy = lab.config.access
        self._sockets_per_login = policy.live_sockets_per_login
        self._sockets_per_rig = policy.live_sockets_per_rig
        self._replay_limit = policy.live_replay_samples
        self.budget = budget if budget is not None else ReplayBudget()
        self._sockets: collections.Counter[tuple[str, int | None]] = collections.Counter()
        self._rig_sockets: collections.Counter[str] = collections.Counter()
        self.hub = LiveFanout([rig.id for rig in lab.config.rigs])
        self._access_delay = access_delay
        self._client_queue = client_queue
        self._session_check = session_check
        self._states: dict[str, tuple[str, str | None]] = {}
        self._signatures: dict[str, tuple[Any, ...]] = {}
        self._checking: asyncio.Task[None] | None = None
        self._check_again = False
        self._watchdog: asyncio.Task[None] | None = None
        lab.logins_ended.subscribe(self.logins_ended)
        lab.tokens.revoked.subscribe(self.tokens_revoked)

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

    def reading(self, rig_id: str, u: float | None, y: float, at: datetime) -> None:
        """Publish an idle-monitoring sample (no run: ``run`` and ``k`` are null)."""
        sample: SampleMessage = {
            "type": "sample",
            "run": None,
            "k": None,
            "t": at.timestamp(),
            "u": u,
            "y": y,
            "channels": {"t": at.timestamp(), "u": u, "y": y},
        }
        self.hub.publish(rig_id, sample)

    # -- the event loop's side --------------------------------------------------------------

    def logins_ended(self, session_ids: frozenset[int]) -> None:
        """Close the connections of logins that ended (any thread)."""
        loop = self.hub.loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._close_logins, session_ids)

    def _close_logins(self, session_ids: frozenset[int]) -> None:
        for client in self.hub.clients():
            if client.key.token_id is None and client.key.session_id in session_ids:
                client.close(CLOSE_UNAUTHORIZED, "your session has ended; log in again")

    def tokens_revoked(self, token_ids: frozenset[int]) -> None:
        """Close the connections of API tokens that were revoked (any thread)."""
        loop = self.hub.loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._close_tokens, token_ids)

    def _close_tokens(self, token_ids: frozenset[int]) -> None:
        for client in self.hub.clients():
            if client.key.token_id is not None and client.key.token_id in token_ids:
                client.close(CLOSE_UNAUTHORIZED, "this API token was revoked")

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Serve clients on ``loop`` (``None`` when the server stops; call in the loop)."""
        self.hub.bind(loop)
        self.budget.bind()
        if self._watchdog is not None:
            self._watchdog.cancel()
            self._watchdog = None
        if loop is not None and self._session_check is not None:
            self._watchdog = loop.create_task(self._check_sessions_forever(self._session_check))

    async def _check_sessions_forever(self, interval: float) -> None:
        while True:
            await asyncio.sleep(interval)
            self._check_sessions()

    def _check_sessions(self) -> None:
        # One check at a time; a request for one while it runs makes it run again.
        if self._checking is not None and not self._checking.done():
            self._check_again = True
            return
        self._checking = asyncio.ensure_future(self._close_ended_sessions())
        self._checking.add_done_callback(_log_failure)

    async def _close_ended_sessions(self) -> None:
        while True:
            self._check_again = False
            clients = self.hub.clients()
            ids = {c.key.session_id for c in clients if c.key.token_id is None}
            tokens = {c.key.token_id for c in clients if c.key.token_id is not None}
            if ids:
                alive = await anyio.to_thread.run_sync(self._alive_sessions, ids)
                for client in clients:
                    if client.key.token_id is None and client.key.session_id not in alive:
                        client.close(CLOSE_UNAUTHORIZED, "your session has ended; log in again")
            if tokens:
                live = await anyio.to_thread.run_sync(self.lab.tokens.alive, tokens)
                for client in clients:
                    token = client.key.token_id
                    if token is not None and token not in live:
                        client.close(CLOSE_UNAUTHORIZED, "this API token was revoked or expired")
            if not self._check_again:
                return

    def _alive_sessions(self, ids: Collection[int | None]) -> set[int | None]:
        now = self.lab.clock.now()
        wanted = [i for i in ids if i is not None]
        with self.lab.db.read() as session:
            alive: set[int | None] = set(
                session.scalars(
                    select(LoginSession.id).where(
                        LoginSession.id.in_(wanted), LoginSession.expires_at > now
                    )
                )
            )
        return alive

    def _refresh(self, rig_id: str) -> None:
        task = asyncio.ensure_future(self._push_access(rig_id))
        task.add_done_callback(_log_failure)

    async def _push_access(self, rig_id: str) -> None:
        channel = self.hub.channels[rig_id]
        snap = await anyio.to_thread.run_sync(self.lab.access.snapshot, rig_id)
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
                    access = _dump(RigOut.of(view))["access"]
                    message: AccessMessage = {"type": "access", "access": access}
                    texts[key] = encode(message)
            return (system.state, system.fault), texts

        state, texts = await anyio.to_thread.run_sync(render)
        if self._states.get(rig_id) != state:
            self._states[rig_id] = state
            changed: StateMessage = {"type": "state", "state": state[0], "detail": state[1]}
            channel.publish(changed)
        for client in clients:
            client.offer(texts[_viewpoint(snap, client.key)])

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
        who = await anyio.to_thread.run_sync(
            lambda: resolve_principal(self.lab, cookie=cookie, authorization=authorization)
        )
        if who is None:
            await websocket.close(CLOSE_UNAUTHORIZED, "not logged in")
            return
        channel = self.hub.channels.get(rig_id)
        if channel is None:
            await websocket.close(CLOSE_UNKNOWN_RIG, f"no rig called {rig_id!r}")
            return
        # One login cannot hold the server's sockets (and replays) for everyone, nor one
        # rig's watchers every connection the server accepts.
        login = who.login_key
        if self._sockets[login] >= self._sockets_per_login:
            await websocket.close(
                CLOSE_TOO_MANY,
                f"at most {self._sockets_per_login} live sockets per login; close one first",
            )
            return
        if self._rig_sockets[rig_id] >= self._sockets_per_rig:
            await websocket.close(
                CLOSE_RIG_FULL,
                f"rig {rig_id!r} has its {self._sockets_per_rig} live sockets; try again later",
            )
            return
        self._sockets[login] += 1
        self._rig_sockets[rig_id] += 1
        try:
            await self._attached(websocket, channel, rig_id, who, since)
        finally:
            _release(self._sockets, login)
            _release(self._rig_sockets, rig_id)

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
                        self.lab.runs.running(rig_id),
                        since,
                        start,
                        user_id=who.user_id,
                        budget=self.budget,
                        limit=self._replay_limit,
                    )
                except ReplayTooSlowError:
                    client.close(CLOSE_TOO_SLOW, "too slow: reconnect with since")
            self.access_changed(rig_id)  # one more watcher
            await _serve(websocket, client, lambda: self._ping(rig_id, who, client), leave)
        except WebSocketDisconnect:
            pass
        finally:
            leave()

    async def _hello(self, websocket: WebSocket, rig_id: str, who: Principal, seq: int) -> None:
        view = await anyio.to_thread.run_sync(self.lab.access.view, rig_id, who)
        rig = _dump(RigOut.of(view))
        run_id = self.lab.runs.running(rig_id)
        run = None
        if run_id is not None:
            record = await anyio.to_thread.run_sync(self.lab.runs.record, run_id)
            run = _dump(RunOut.of(record))
        hello: HelloMessage = {
            "type": "hello",
            "rig": rig,
            "access": rig["access"],
            "run": run,
            "seq": seq,
        }
        await websocket.send_text(encode(hello))

    def _ping(self, rig_id: str, who: Principal, client: LiveClient) -> None:
        # A ping is the client being here: it keeps a control or queue place alive. Looking
        # at the rig writes the heartbeat (at most once a second, and only when needed).
        now = self.lab.clock.now()
        if client.last_ping is not None and now - client.last_ping < _PING_INTERVAL:
            return
        client.last_ping = now
        self.lab.presence.touch(rig_id, who.username)
        self.lab.access.view(rig_id, who)


async def _serve(
    websocket: WebSocket, client: LiveClient, on_ping: Any, leave: Callable[[], None]
) -> None:
    """Send the client's queue and read its messages until either side stops (then ``leave``)."""

    async def send() -> None:
        while client.closing is None:
            await client.wake.wait()
            client.wake.clear()
            # Everything queued goes in one frame: a client that fell behind catches up
            # in one send instead of one per message.
            while (frame := client.next_frame()) is not None:
                await websocket.send_text(frame)
                client.sent += 1

    async def receive() -> None:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            if text is None:
                text = (message.get("bytes") or b"").decode("utf-8", errors="replace")
            # An oversized or over-deep message is answered like any bad message: the
            # socket stays open (a client's mistake is not a reason to cut its stream).
            kind = client_message_type(text)
            if kind == "ping":
                await anyio.to_thread.run_sync(on_ping)
                client.offer('{"type":"pong"}')
            else:
                error: ErrorMessage = {"type": "error", "detail": kind}
                client.offer(encode(error))

    # The client being cut ends the connection at once, even while a send waits for a
    # stalled socket to drain (the send is abandoned; nothing of it was written).
    tasks = [
        asyncio.ensure_future(send()),
        asyncio.ensure_future(receive()),
        asyncio.ensure_future(client.ended.wait()),
    ]
    try:
        done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        for task in done:
            exc = task.exception()
            if exc is not None and not isinstance(exc, WebSocketDisconnect):
                raise exc
    finally:
        for task in tasks:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(BaseException):
                await task
        leave()
        if (
            websocket.client_state is WebSocketState.CONNECTED
            and websocket.application_state is WebSocketState.CONNECTED
        ):
            code, reason = client.closing or (1000, "")
            # The close frame waits behind what the socket still holds; a peer that never
            # reads again is left to the server, which closes the connection.
            with contextlib.suppress(Exception):
                await asyncio.wait_for(websocket.close(code, reason), _CLOSE_TIMEOUT)


def _release(counts: collections.Counter[Any], key: Any) -> None:
    counts[key] -= 1
    if counts[key] <= 0:
        del counts[key]


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
