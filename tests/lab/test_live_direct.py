"""The live stream written straight to the sockets (``thermolab serve``'s uvicorn protocol).

A real uvicorn server on loopback runs the app with the WebSocket protocol
``thermolab serve`` uses, which offers the stream a
:class:`~thermolab.lab.live.fanout.FrameWriter`: caught-up clients get each batch's
one frame written to their socket, with no per-client task or ASGI call.
These tests check that the stream stays whole and in order that way, that a
socket that stops reading is still cut, and that a plain watcher's ping
never reaches the store (a controller's still keeps its turn).
"""

from __future__ import annotations

import contextlib
import json
import socket
import threading
from collections.abc import Iterator
from datetime import UTC, datetime
from typing import Any

import pytest
import uvicorn
from websockets.sync.client import ClientConnection, connect

from thermolab.cli.http_server import _framed_websockets
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.http.app import create_app
from thermolab.lab.http.live_socket import LiveEndpoint
from thermolab.lab.live.fanout import CLOSE_TOO_SLOW
from thermolab.lab.service import Lab

from .conftest import LabFactory
from .test_live import login
from .test_runs import until


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


@pytest.fixture
def served(make_lab: LabFactory) -> Iterator[tuple[Lab, LiveEndpoint, str]]:
    lab = make_lab()
    for name in ("ana", "bob"):
        lab.users.add(name, "correct horse", "student")
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    config = uvicorn.Config(
        app,
        host="127.0.0.1",
        port=port,
        log_level="warning",
        ws_per_message_deflate=False,
        ws=_framed_websockets(),
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        until(lambda: server.started)
        yield lab, app.state.live, f"ws://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=30)


def _messages(ws: ClientConnection, timeout: float = 5.0) -> list[dict[str, Any]]:
    frame = json.loads(ws.recv(timeout=timeout))
    return frame if isinstance(frame, list) else [frame]


def _readings(ws: ClientConnection, count: int) -> list[dict[str, Any]]:
    """The next ``count`` samples, live (``sample``) or replayed (``samples`` items)."""
    got: list[dict[str, Any]] = []
    while len(got) < count:
        for message in _messages(ws):
            if message["type"] == "sample":
                got.append(message)
            elif message["type"] == "samples":
                got += message["items"]
    return got


def test_caught_up_watchers_are_written_directly_and_miss_nothing(
    served: tuple[Lab, LiveEndpoint, str],
) -> None:
    lab, live, base = served
    url = base + "/api/rigs/other/live"
    with (
        connect(url, additional_headers=login(lab, "ana")) as ana,
        connect(url, additional_headers=login(lab, "bob")) as bob,
    ):
        hello = _messages(ana)[0]
        assert hello["type"] == "hello"
        assert _messages(bob)[0]["type"] == "hello"
        channel = live.hub.channels["other"]
        until(lambda: len(channel.clients()) == 2)
        until(lambda: all(c.direct is not None for c in channel.clients()))
        at = datetime.now(UTC)
        for k in range(300):
            live.reading("other", 0.0, float(k), at)
        for ws in (ana, bob):
            got = _readings(ws, 300)
            assert [m["y"] for m in got] == [float(k) for k in range(300)]
            seqs = [m["seq"] for m in got]
            assert seqs == list(range(seqs[0], seqs[0] + 300))
        # A reconnecting watcher gets what it missed, then the live stream, once each.
        last = seqs[-1]
        for k in range(300, 310):
            live.reading("other", 0.0, float(k), at)
    with connect(f"{url}?since={last}", additional_headers=login(lab, "ana")) as again:
        assert _messages(again)[0]["type"] == "hello"
        live.reading("other", 0.0, 310.0, at)
        got = _readings(again, 11)
        assert [m["y"] for m in got] == [float(k) for k in range(300, 311)]


def test_a_socket_that_stops_reading_is_cut_by_its_unsent_bytes(
    served: tuple[Lab, LiveEndpoint, str],
) -> None:
    lab, live, base = served
    port = int(base.rsplit(":", 1)[1])
    cookie = login(lab, "ana")["cookie"]
    with socket.create_connection(("127.0.0.1", port)) as stalled:
        stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        stalled.sendall(
            (
                "GET /api/rigs/other/live HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                f"Cookie: {cookie}\r\n\r\n"
            ).encode()
        )
        assert stalled.recv(12) == b"HTTP/1.1 101"  # then it never reads again
        channel = live.hub.channels["other"]
        until(lambda: bool(channel.clients()) and channel.clients()[0].direct is not None)
        client = channel.clients()[0]
        big = "x" * 60_000
        for _ in range(400):  # 24 MB: more than the socket buffers and the unsent bound
            live.hub.publish("other", {"type": "state", "state": "ready", "detail": big})
            if client.closing is not None:
                break
        until(lambda: client.closing is not None)
        assert client.closing == (CLOSE_TOO_SLOW, "too slow: reconnect with since")
        until(lambda: not channel.clients())


def looks_at_the_store(lab: Lab, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Bob controls the rig; the list fills with whom each ``access.view`` was for."""
    viewed: list[str] = []
    view = lab.access.view

    def counted(rig_id: str, who: Any) -> Any:
        viewed.append(who.username)
        return view(rig_id, who)

    monkeypatch.setattr(lab.access, "view", counted)
    bob = lab.users.get("bob")
    lab.access.request_control("other", Principal(bob.id, bob.username, bob.role))
    return viewed


def test_a_watchers_ping_stays_in_memory_and_a_controllers_keeps_the_turn(
    served: tuple[Lab, LiveEndpoint, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    lab, live, base = served
    viewed = looks_at_the_store(lab, monkeypatch)
    url = base + "/api/rigs/other/live"
    with (
        connect(url, additional_headers=login(lab, "ana")) as ana,
        connect(url, additional_headers=login(lab, "bob")) as bob_ws,
    ):
        for ws in (ana, bob_ws):
            assert _messages(ws)[0]["type"] == "hello"
        until(lambda: "other" in live._holders)  # the first access snapshot is in
        viewed.clear()
        for ws in (ana, bob_ws):
            ws.send('{"type":"ping"}')
            while not any(m["type"] == "pong" for m in _messages(ws)):
                pass
        assert viewed == ["bob"]  # only the controller's ping looked at the store
        assert {w.username for w in lab.presence.watchers("other")} == {"ana", "bob"}


def test_a_controllers_many_sockets_keep_the_turn_with_one_look_a_second(
    served: tuple[Lab, LiveEndpoint, str], monkeypatch: pytest.MonkeyPatch, clock: ManualClock
) -> None:
    # Per socket, 2000 of one login's sockets pinging queued store work without bound,
    # their reads stopped meanwhile and the server failed them on its own keepalive (1011).
    lab, live, base = served
    viewed = looks_at_the_store(lab, monkeypatch)
    url = base + "/api/rigs/other/live"
    with contextlib.ExitStack() as stack:
        tabs = [
            stack.enter_context(connect(url, additional_headers=login(lab, "bob")))
            for _ in range(4)
        ]
        for ws in tabs:
            assert _messages(ws)[0]["type"] == "hello"
        until(lambda: "other" in live._holders)
        viewed.clear()
        for ws in tabs:
            ws.send('{"type":"ping"}')
        for ws in tabs:  # every ping is answered, the skipped ones too
            while not any(m["type"] == "pong" for m in _messages(ws)):
                pass
        assert viewed == ["bob"]  # one look at the store for all four
        clock.advance(1.1)  # a second later the place is kept again
        tabs[0].send('{"type":"ping"}')
        while not any(m["type"] == "pong" for m in _messages(tabs[0])):
            pass
        assert viewed == ["bob", "bob"]


def test_clients_joining_at_once_share_one_reading_and_each_sees_the_rig_as_theirs(
    served: tuple[Lab, LiveEndpoint, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A class joining at the bell: the hellos of everyone who joins while one is read
    come from one reading of the rig, each still as its client sees it (the controller,
    the queued student, a teacher with the queue, plain watchers) and each numbered
    from its own place in the stream."""
    lab, live, base = served
    lab.users.add("tina", "correct horse", "teacher")
    watchers = [f"w{i}" for i in range(12)]
    for name in ("cy", *watchers):
        lab.users.add(name, "correct horse", "student")
    for name in ("ana", "bob"):  # Ana controls, Bob waits
        user = lab.users.get(name)
        lab.access.request_control("other", Principal(user.id, user.username, user.role))
    url = base + "/api/rigs/other/live"

    # The first reading is held until everyone else has joined: they wait for the next.
    reads: list[str] = []
    first_read = threading.Event()
    release = threading.Event()
    view = lab.access.view

    def counted_view(rig_id: str, who: Principal, **kwargs: Any) -> Any:
        reads.append(who.username)
        if len(reads) == 1:
            first_read.set()
            assert release.wait(30)
        return view(rig_id, who, **kwargs)

    monkeypatch.setattr(lab.access, "view", counted_view)
    names = ["cy", "ana", "bob", "tina", *watchers]
    hellos: dict[str, dict[str, Any]] = {}
    with contextlib.ExitStack() as stack:
        first = stack.enter_context(connect(url, additional_headers=login(lab, "cy")))
        assert first_read.wait(10)
        others: dict[str, ClientConnection] = {}

        def join(name: str) -> None:
            others[name] = stack.enter_context(connect(url, additional_headers=login(lab, name)))

        joiners = [threading.Thread(target=join, args=(name,)) for name in names[1:]]
        for thread in joiners:
            thread.start()
        for thread in joiners:
            thread.join(10)
        channel = live.hub.channels["other"]
        until(lambda: len(channel.clients()) == len(names))  # all attached, all waiting
        release.set()
        for name, ws in {"cy": first, **others}.items():
            hellos[name] = _messages(ws)[0]
        # After the hellos, the stream: each client's next sample comes after its hello.
        live.reading("other", 0.0, 1.0, datetime.now(UTC))
        for name, ws in {"cy": first, **others}.items():
            sample = _readings(ws, 1)[0]
            assert sample["seq"] == hellos[name]["seq"] + 1, name
    # One reading for Cy, one for the batch that joined meanwhile (whose first member's
    # view is its reading), and one more for each place holder: their heartbeat.
    assert len(reads) <= 4, reads
    assert all(h["type"] == "hello" for h in hellos.values())
    roles = {name: h["access"]["role"] for name, h in hellos.items()}
    assert roles["ana"] == "controller"
    assert roles["bob"] == "queued"
    assert hellos["bob"]["access"]["queuePosition"] == 1
    assert {roles[name] for name in ("cy", "tina", *watchers)} == {"watcher"}
    assert all(h["access"]["controller"] == "ana" for h in hellos.values())
    # Only the teacher's hello names the queue and the watchers.
    assert [slot["username"] for slot in hellos["tina"]["rig"]["queue"]] == ["bob"]
    for name in ("cy", "ana", "bob", *watchers):
        assert hellos[name]["rig"]["queue"] is None, name
        assert hellos[name]["rig"]["watcherList"] is None, name
