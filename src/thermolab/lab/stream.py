"""The live WebSocket ``/api/rigs/{rig}/live`` (contract: ``docs/live-protocol.md``).

:class:`LiveBroadcaster` listens to the lab (access changes, runs, runner
events, idle readings), turns what it hears into the protocol's messages on
each rig's :class:`~thermolab.lab.live.LiveChannel`, and serves the clients:
``hello``, the replay of what a reconnecting client missed (from memory, or
the current run's samples from the store when memory no longer has them),
then the live messages. A client's ``ping`` keeps its control or queue place
alive and is answered with ``pong``.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from datetime import datetime, timedelta
from typing import Any

import anyio.to_thread
from starlette.websockets import WebSocket, WebSocketDisconnect, WebSocketState

from thermolab.lab.access import RigSnapshot
from thermolab.lab.api import COOKIE_NAME
from thermolab.lab.live import (
    CLOSE_TOO_BIG,
    CLOSE_TOO_SLOW,
    CLOSE_UNAUTHORIZED,
    CLOSE_UNKNOWN_RIG,
    MAX_CLIENT_MESSAGE,
    LiveClient,
    LiveHub,
    encode,
)
from thermolab.lab.models import Role
from thermolab.lab.runs import RunRecord
from thermolab.lab.schemas import RigOut, RunOut
from thermolab.lab.service import Lab
from thermolab.lab.users import Principal
from thermolab.runner import EstimateEvent, Event, SampleEvent

__all__ = ["LiveBroadcaster"]

log = logging.getLogger(__name__)

_REPLAY_BATCH = 1000
_PING_INTERVAL = timedelta(seconds=1)  # pings look at the rig at most this often


def _dump(model: RigOut | RunOut) -> dict[str, Any]:
    return model.model_dump(mode="json", by_alias=True)


class LiveBroadcaster:
    """The lab's live stream: a :class:`~thermolab.lab.service.LabListener` and the endpoint.

    Parameters
    ----------
    lab : Lab
    access_delay : float
        Seconds over which access changes are gathered into one ``access``
        message per client.
    client_queue : int
        Messages a client may have waiting before it is cut as too slow.
    """

    def __init__(self, lab: Lab, *, access_delay: float = 0.2, client_queue: int = 2000) -> None:
        self.lab = lab
        self.hub = LiveHub([rig.id for rig in lab.config.rigs])
        self._access_delay = access_delay
        self._client_queue = client_queue
        self._states: dict[str, tuple[str, str | None]] = {}
        self._signatures: dict[str, tuple[Any, ...]] = {}

    # -- the lab's side (worker threads) ---------------------------------------------------

    def access_changed(self, rig_id: str) -> None:
        """Schedule one ``access`` (and ``state``) update of every client of the rig."""
        self.hub.access_changed(rig_id, self._refresh, self._access_delay)

    def run_changed(self, rig_id: str, event: str, record: RunRecord) -> None:
        """Publish ``run`` (started / ended)."""
        self.hub.publish(rig_id, {"type": "run", "event": event, "run": _dump(RunOut.of(record))})

    def run_event(self, rig_id: str, run_id: int, event: Event) -> None:
        """Publish a run's samples and estimates."""
        if isinstance(event, SampleEvent):
            self.hub.publish(
                rig_id,
                {
                    "type": "sample",
                    "run": run_id,
                    "k": event.k,
                    "t": event.t,
                    "u": event.u,
                    "y": event.y,
                },
            )
        elif isinstance(event, EstimateEvent):
            estimate = event.estimate.to_dict()
            self.hub.publish(
                rig_id,
                {
                    "type": "estimate",
                    "run": run_id,
                    "method": event.method,
                    "k": event.k,
                    "K": estimate.get("K"),
                    "tau": estimate.get("tau"),
                    "W": estimate.get("W"),
                    "valid": estimate.get("valid"),
                    "final": event.final,
                },
            )

    def reading(self, rig_id: str, u: float | None, y: float, at: datetime) -> None:
        """Publish an idle-monitoring sample (no run: ``run`` and ``k`` are null)."""
        self.hub.publish(
            rig_id, {"type": "sample", "run": None, "k": None, "t": at.timestamp(), "u": u, "y": y}
        )

    # -- the event loop's side --------------------------------------------------------------

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Serve clients on ``loop`` (``None`` when the server stops)."""
        self.hub.bind(loop)

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
                    texts[key] = encode({"type": "access", "access": access})
            return (system.state, system.fault), texts

        state, texts = await anyio.to_thread.run_sync(render)
        if self._states.get(rig_id) != state:
            self._states[rig_id] = state
            channel.publish({"type": "state", "state": state[0], "detail": state[1]})
        for client in clients:
            client.offer(texts[_viewpoint(snap, client.key)])

    async def endpoint(self, websocket: WebSocket, rig_id: str, since: int | None = None) -> None:
        """Serve one client (the WebSocket route)."""
        await websocket.accept()
        token = websocket.cookies.get(COOKIE_NAME)
        who = await anyio.to_thread.run_sync(self.lab.sessions.resolve, token)
        if who is None:
            await websocket.close(CLOSE_UNAUTHORIZED, "not logged in")
            return
        channel = self.hub.channels.get(rig_id)
        if channel is None:
            await websocket.close(CLOSE_UNKNOWN_RIG, f"no rig called {rig_id!r}")
            return
        client = LiveClient(key=who, maxsize=self._client_queue)
        presence = self.lab.presence.connect(rig_id, who.username)
        start = channel.attach(client)
        try:
            await self._hello(websocket, rig_id, who, start)
            if since is not None and since < start:
                await self._replay(websocket, rig_id, since, start)
            self.access_changed(rig_id)  # one more watcher
            await _serve(websocket, client, lambda: self._ping(rig_id, who, client))
        except WebSocketDisconnect:
            pass
        finally:
            channel.detach(client)
            self.lab.presence.disconnect(presence)
            self.access_changed(rig_id)

    async def _hello(self, websocket: WebSocket, rig_id: str, who: Principal, seq: int) -> None:
        view = await anyio.to_thread.run_sync(self.lab.access.view, rig_id, who)
        rig = _dump(RigOut.of(view))
        run_id = self.lab.runs.running(rig_id)
        run = None
        if run_id is not None:
            record = await anyio.to_thread.run_sync(self.lab.runs.record, run_id)
            run = _dump(RunOut.of(record))
        await websocket.send_text(
            encode({"type": "hello", "rig": rig, "access": rig["access"], "run": run, "seq": seq})
        )

    async def _replay(self, websocket: WebSocket, rig_id: str, since: int, upto: int) -> None:
        channel = self.hub.channels[rig_id]
        kept, gap = channel.replay_since(since, upto)
        run_id = self.lab.runs.running(rig_id)
        if gap and run_id is not None:
            # Memory no longer has everything missed: the current run's samples from the store.
            rows = await anyio.to_thread.run_sync(self._stored_samples, run_id)
            for i in range(0, len(rows), _REPLAY_BATCH):
                stored = [
                    {"run": run_id, "k": k, "t": t, "u": u, "y": y}
                    for k, t, u, y in rows[i : i + _REPLAY_BATCH]
                ]
                await websocket.send_text(encode({"type": "samples", "items": stored}))
        # In the order they happened; runs of consecutive samples go as one batch.
        batch: list[dict[str, Any]] = []
        for message in [*kept, None]:
            if message is not None and message["type"] == "sample":
                batch.append({k: v for k, v in message.items() if k != "type"})
                if len(batch) < _REPLAY_BATCH:
                    continue
            if batch:
                last = batch[-1]["seq"]
                await websocket.send_text(encode({"type": "samples", "seq": last, "items": batch}))
                batch = []
            if message is not None and message["type"] != "sample":
                await websocket.send_text(encode(message))

    def _stored_samples(self, run_id: int) -> list[tuple[int, float, float, float]]:
        return list(self.lab.runs.samples(run_id, _NOBODY))

    def _ping(self, rig_id: str, who: Principal, client: LiveClient) -> None:
        # A ping is the client being here: it keeps a control or queue place alive. Looking
        # at the rig writes the heartbeat (at most once a second, and only when needed).
        now = self.lab.clock.now()
        if client.last_ping is not None and now - client.last_ping < _PING_INTERVAL:
            return
        client.last_ping = now
        self.lab.presence.touch(rig_id, who.username)
        self.lab.access.view(rig_id, who)


async def _serve(websocket: WebSocket, client: LiveClient, on_ping: Any) -> None:
    """Send the client's queue and read its messages until either side stops."""

    async def send() -> None:
        while True:
            await client.wake.wait()
            client.wake.clear()
            if client.cut:
                await websocket.close(CLOSE_TOO_SLOW, "too slow: reconnect with since")
                return
            while client.queue:
                await websocket.send_text(client.queue.popleft())
                client.sent += 1

    async def receive() -> None:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            if text is None:
                text = (message.get("bytes") or b"").decode("utf-8", errors="replace")
            if len(text) > MAX_CLIENT_MESSAGE:
                await websocket.close(
                    CLOSE_TOO_BIG, f"messages are at most {MAX_CLIENT_MESSAGE} bytes"
                )
                return
            kind = _message_type(text)
            if kind == "ping":
                await anyio.to_thread.run_sync(on_ping)
                client.offer('{"type":"pong"}')
            else:
                client.offer(encode({"type": "error", "detail": kind}))

    tasks = [asyncio.ensure_future(send()), asyncio.ensure_future(receive())]
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
        if websocket.client_state is WebSocketState.CONNECTED:
            with contextlib.suppress(Exception):
                await websocket.close()


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


def _message_type(text: str) -> str:
    """``"ping"`` for a ping, else the problem with the message, in words."""
    try:
        data = json.loads(text)
    except ValueError:
        return 'messages must be JSON objects such as {"type": "ping"}'
    if not isinstance(data, dict):
        return 'messages must be JSON objects such as {"type": "ping"}'
    kind = data.get("type")
    if kind == "ping":
        return "ping"
    return (
        f"unknown message type {kind!r}; the only one is 'ping' (commands go through the HTTP API)"
    )


def _log_failure(task: asyncio.Future[None]) -> None:
    if not task.cancelled() and task.exception() is not None:
        log.error("live access update failed", exc_info=task.exception())


# Renders a rig for nobody in particular (state, and the lab's own replays): a teacher's view.
_NOBODY = Principal(user_id=-1, username="(live)", role=Role.TEACHER)
