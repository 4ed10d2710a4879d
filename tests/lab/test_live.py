"""The live WebSocket: hello, run messages in order, replay, presence, pings, slow clients."""

from __future__ import annotations

import contextlib
import json
import math
import socket
import threading
import time
import weakref
from collections import deque
from collections.abc import Iterator
from typing import Any

import pytest
import uvicorn
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect
from websockets.client import ClientProtocol
from websockets.frames import Frame, Opcode
from websockets.sync.client import connect
from websockets.uri import parse_uri

from thermolab.lab.clock import ManualClock
from thermolab.lab.config import RigConfig
from thermolab.lab.http.app import create_app
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.http.live_socket import LiveEndpoint
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory
from .test_runs import StepClock, until


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    """The stream is in memory; its database side is tested on both backends elsewhere."""
    return sqlite_url


@pytest.fixture
def step_clock() -> Iterator[StepClock]:
    clock = StepClock()
    yield clock
    clock.allow(math.inf)


def make(make_lab: LabFactory, clock: Any = None) -> tuple[Lab, TestClient, LiveEndpoint]:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper" if rig.id == "twin" else "tclab", clock=clock or VirtualClock())

    lab = make_lab(opener=opener)
    for name in ("ana", "ben"):
        lab.users.add(name, PASSWORD, "student")
    lab.users.add("tina", PASSWORD, "teacher", admin=True)
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    client = TestClient(app)
    live: LiveEndpoint = app.state.live
    return lab, client, live


def login(lab: Lab, name: str) -> dict[str, str]:
    """Headers of a logged-in user (sessions opened directly: the client keeps no cookies)."""
    token, _ = lab.sessions.create(lab.users.get(name))
    return {"cookie": f"{COOKIE_NAME}={token}"}


_frames: weakref.WeakKeyDictionary[Any, deque[dict[str, Any]]] = weakref.WeakKeyDictionary()


def receive(ws: Any) -> dict[str, Any]:
    """The next message: a frame holds one, or a JSON array of several (in order)."""
    buffered = _frames.setdefault(ws, deque())
    while not buffered:
        frame = ws.receive_json()
        buffered.extend(frame if isinstance(frame, list) else [frame])
    return buffered.popleft()


def receive_until(ws: Any, kind: str, **match: Any) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Receive until a message of ``kind`` (with the given fields); return it and all before."""
    seen = []
    for _ in range(10_000):
        message = receive(ws)
        seen.append(message)
        if message["type"] == kind and all(message.get(k) == v for k, v in match.items()):
            return message, seen
    raise AssertionError(f"no {kind} message")


def test_hello_then_a_run_in_order(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        ana = login(lab, "ana")
        with client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws:
            hello = ws.receive_json()
            assert hello["type"] == "hello"
            assert (hello["rig"]["id"], hello["rig"]["state"], hello["run"]) == (
                "twin",
                "off",
                None,
            )
            assert hello["access"]["role"] == "watcher"
            assert isinstance(hello["seq"], int)
            assert hello["seq"] < 2**53  # exact in a browser
            client.post("/api/rigs/twin/control", headers=ana)
            response = client.post(
                "/api/rigs/twin/runs",
                headers=ana,
                json={"dt": 1, "samples": 60, "signal": "step:0:10@5", "methods": ["lsm", "wlsm"]},
            )
            run_id = response.json()["id"]
            ended, seen = receive_until(ws, "run", event="ended")
            # Access views are rendered off the event loop, so the one that says "controller"
            # may come after a short run has already ended; it must come all the same.
            later = []
            while not any(
                m["type"] == "access" and m["access"]["role"] == "controller" for m in seen + later
            ):
                later.append(receive(ws))
        started = next(m for m in seen if m["type"] == "run")
        assert (started["event"], started["run"]["id"]) == ("started", run_id)
        # The run-start message describes every channel a sample carries, with its unit.
        described = {c["name"]: (c["unit"], c["role"]) for c in started["run"]["channels"]}
        assert (described["u"], described["y"], described["t"]) == (
            ("V", "input"),
            ("V", "output"),
            ("s", "time"),
        )
        samples = [m for m in seen if m["type"] == "sample"]
        assert [m["k"] for m in samples] == list(range(60))
        assert {m["run"] for m in samples} == {run_id}
        assert samples[10]["u"] == 10.0
        # Every channel of the sample by name (additive to t, u, y, k).
        channels = samples[10]["channels"]
        assert list(channels) == list(described)
        assert list(channels) == ["t", "u", "y", "k", "t_read", "jitter", "lateness"]
        assert (channels["u"], channels["k"]) == (10.0, 10)
        estimates = [m for m in seen if m["type"] == "estimate"]
        assert {m["method"] for m in estimates} == {"lsm", "wlsm"}
        assert any(m["final"] and m["method"] == "lsm" for m in estimates)
        assert all({"K", "tau", "W", "valid", "k", "reason"} <= set(m) for m in estimates)
        # An estimate without a model says why; one with a model has no reason.
        assert all(bool(m["reason"]) != m["valid"] for m in estimates)
        numbered = [m["seq"] for m in seen if "seq" in m]
        assert numbered == sorted(numbered)
        assert len(set(numbered)) == len(numbered)
        assert numbered[0] > hello["seq"]
        assert ended["run"]["status"] == "finished"
        roles = [m["access"]["role"] for m in seen + later if m["type"] == "access"]
        assert "controller" in roles


def test_a_reconnecting_client_gets_what_it_missed(make_lab: LabFactory) -> None:
    lab, client, _live = make(make_lab)
    with client:
        ana = login(lab, "ana")
        client.post("/api/rigs/twin/control", headers=ana)
        with client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws:
            since = ws.receive_json()["seq"]
        client.post(
            "/api/rigs/twin/runs", headers=ana, json={"dt": 1, "samples": 30, "methods": ["lsm"]}
        )
        lab.runs.wait("twin", timeout=30)
        with client.websocket_connect(f"/api/rigs/twin/live?since={since}", headers=ana) as ws:
            hello = ws.receive_json()
            missed = [ws.receive_json() for _ in range(4)]
        # In the order they happened, the samples in one batch.
        assert [m["type"] for m in missed] == ["run", "samples", "estimate", "run"]
        started, batch, final, ended = missed
        assert (started["event"], ended["event"], final["final"]) == ("started", "ended", True)
        assert [item["k"] for item in batch["items"]] == list(range(30))
        assert batch["seq"] == batch["items"][-1]["seq"]
        assert started["seq"] < batch["items"][0]["seq"] < final["seq"] < ended["seq"]
        assert ended["seq"] == hello["seq"]


def test_a_gap_too_old_for_memory_is_filled_from_the_store(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab, client, live = make(make_lab, step_clock)
    live.hub.channels["twin"]._ring = type(live.hub.channels["twin"]._ring)(maxlen=5)
    with client:
        ana = login(lab, "ana")
        client.post("/api/rigs/twin/control", headers=ana)
        with client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws:
            since = ws.receive_json()["seq"]
        run_id = client.post(
            "/api/rigs/twin/runs", headers=ana, json={"dt": 1, "samples": 100, "methods": ["lsm"]}
        ).json()["id"]
        step_clock.allow(39.0)
        until(lambda: lab.runs.record(run_id).samples_stored == 40)
        with client.websocket_connect(f"/api/rigs/twin/live?since={since}", headers=ana) as ws:
            hello = ws.receive_json()
            assert hello["run"]["id"] == run_id
            stored = ws.receive_json()
            assert stored["type"] == "samples"
            assert [item["k"] for item in stored["items"]] == list(range(40))
            assert "seq" not in stored["items"][0]
        step_clock.allow(math.inf)
        lab.runs.wait("twin", timeout=30)


def test_refusals_close_with_the_protocol_codes(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        with (
            client.websocket_connect("/api/rigs/twin/live") as ws,
            pytest.raises(WebSocketDisconnect) as info,
        ):
            ws.receive_json()
        assert info.value.code == 4401
        ana = login(lab, "ana")
        with (
            client.websocket_connect("/api/rigs/nope/live", headers=ana) as ws,
            pytest.raises(WebSocketDisconnect) as info,
        ):
            ws.receive_json()
        assert info.value.code == 4404
        with client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws:
            ws.receive_json()
            ws.send_text(json.dumps({"type": "input", "u": 5}))
            error, _ = receive_until(ws, "error")
            assert "only one is 'ping'" in error["detail"]
            # Oversized or over-deep messages get an error, and the socket stays open.
            ws.send_text("x" * 5000)
            error, _ = receive_until(ws, "error")
            assert "at most 4096 bytes" in error["detail"]
            ws.send_text("[" * 2000 + "]" * 2000)
            error, _ = receive_until(ws, "error")
            assert "at most 8 levels" in error["detail"]
            ws.send_text(json.dumps({"type": "ping"}))
            receive_until(ws, "pong")
        # The session survived all of that.
        assert client.get("/api/session", headers=ana).status_code == 200


def test_pings_keep_control_and_connections_count_as_watchers(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab, client, _ = make(make_lab)
    with client:
        ana, tina = login(lab, "ana"), login(lab, "tina")
        client.post("/api/rigs/twin/control", headers=ana)
        with (
            client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws,
            client.websocket_connect("/api/rigs/twin/live", headers=ana) as second,
        ):
            ws.receive_json()
            second.receive_json()
            rig = client.get("/api/rigs/twin", headers=tina).json()
            ana_watching = next(w for w in rig["watcherList"] if w["username"] == "ana")
            assert ana_watching["connections"] == 2
            for _ in range(6):  # a minute with only the socket's pings
                clock.advance(10)
                ws.send_text('{"type": "ping"}')
                receive_until(ws, "pong")
                lab.sweep()
            assert lab.access.snapshot("twin").controller is not None
        clock.advance(16)  # the socket is gone, and so is the client
        lab.sweep()
        assert lab.access.snapshot("twin").controller is None


def test_a_slow_client_is_cut_and_the_others_are_not(make_lab: LabFactory) -> None:
    lab, client, live = make(make_lab)
    live._client_queue = 50
    with client:
        ana, ben = login(lab, "ana"), login(lab, "ben")
        with client.websocket_connect("/api/rigs/twin/live", headers=ana) as slow:
            slow.receive_json()
            live._client_queue = 10_000
            with client.websocket_connect("/api/rigs/twin/live", headers=ben) as fast:
                fast.receive_json()
                channel = live.hub.channels["twin"]
                loop = live.hub.loop
                assert loop is not None

                def burst() -> None:  # 100 messages before either client's sender runs
                    for k in range(100):
                        channel.publish(
                            {"type": "sample", "run": None, "k": k, "t": k, "u": 0, "y": 0}
                        )

                loop.call_soon_threadsafe(burst)
                got = [receive(fast) for _ in range(100)]
                assert [m["k"] for m in got if m["type"] == "sample"][-1] == 99
                with pytest.raises(WebSocketDisconnect) as info:
                    receive_until(slow, "never")
                assert info.value.code == 4408


def test_a_plain_http_request_to_the_live_path_is_a_json_error(make_lab: LabFactory) -> None:
    _, client, _ = make(make_lab)
    with client:
        response = client.get("/api/rigs/twin/live")
        assert response.status_code == 401
        assert response.json()["detail"] == "not logged in"


def closed_with(ws: Any, within: float = 10.0) -> int:
    """Read until the server closes the socket (in time); return the close code."""
    start = time.monotonic()
    with pytest.raises(WebSocketDisconnect) as info:
        receive_until(ws, "never")
    assert time.monotonic() - start < within
    return info.value.code


def still_open(ws: Any) -> bool:
    ws.send_text('{"type": "ping"}')
    receive_until(ws, "pong")
    return True


def test_a_client_behind_gets_its_backlog_in_one_frame_in_order(make_lab: LabFactory) -> None:
    lab, client, live = make(make_lab)
    with client:
        with client.websocket_connect("/api/rigs/twin/live", headers=login(lab, "ana")) as ws:
            ws.receive_json()  # hello
            channel = live.hub.channels["twin"]
            loop = live.hub.loop
            assert loop is not None

            def burst() -> None:  # published before the client's sender runs
                for k in range(10):
                    channel.publish({"type": "sample", "run": 1, "k": k, "t": k, "u": 0, "y": 0})

            loop.call_soon_threadsafe(burst)
            frame = None
            while not isinstance(frame, list):  # an access update may come first
                frame = ws.receive_json()
        assert [m["k"] for m in frame] == list(range(10))
        assert [m["seq"] for m in frame] == sorted(m["seq"] for m in frame)


def test_logging_out_closes_that_logins_sockets_only(make_lab: LabFactory) -> None:
    lab, client, live = make(make_lab)
    live._session_check = 60.0  # the logout itself closes them, not the periodic check
    with client:
        first, second, ben = login(lab, "ana"), login(lab, "ana"), login(lab, "ben")
        with (
            client.websocket_connect("/api/rigs/twin/live", headers=first) as ws1,
            client.websocket_connect("/api/rigs/other/live", headers=first) as ws1b,
            client.websocket_connect("/api/rigs/twin/live", headers=second) as ws2,
            client.websocket_connect("/api/rigs/twin/live", headers=ben) as wsb,
        ):
            for ws in (ws1, ws1b, ws2, wsb):
                ws.receive_json()
            assert client.delete("/api/session", headers=first).status_code == 204
            assert closed_with(ws1) == 4401
            assert closed_with(ws1b) == 4401
            assert still_open(ws2)
            assert still_open(wsb)


def test_removing_an_account_or_changing_a_password_closes_its_sockets(
    make_lab: LabFactory,
) -> None:
    lab, client, live = make(make_lab)
    live._session_check = 60.0
    with client:
        first, second = login(lab, "ana"), login(lab, "ana")
        ben, tina = login(lab, "ben"), login(lab, "tina")
        with (
            client.websocket_connect("/api/rigs/twin/live", headers=first) as ws1,
            client.websocket_connect("/api/rigs/twin/live", headers=second) as ws2,
            client.websocket_connect("/api/rigs/twin/live", headers=ben) as wsb,
        ):
            for ws in (ws1, ws2, wsb):
                ws.receive_json()
            # A new password from the second login ends the first (and keeps its own).
            changed = client.put(
                "/api/users/ana/password",
                headers=second,
                json={"password": "a new password", "currentPassword": PASSWORD},
            )
            assert changed.status_code == 204
            assert closed_with(ws1) == 4401
            assert still_open(ws2)
            assert client.delete("/api/users/ana", headers=tina).status_code == 204
            assert closed_with(ws2) == 4401
            assert still_open(wsb)


def test_a_login_ended_elsewhere_closes_its_sockets_within_the_check_interval(
    make_lab: LabFactory,
) -> None:
    lab, client, live = make(make_lab)
    live._session_check = 0.05  # read when the app starts
    with client:
        ana = login(lab, "ana")
        with client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws:
            ws.receive_json()
            lab.users.remove("ana")  # as `thermolab user remove` does, in another process
            assert closed_with(ws) == 4401


def test_seq_grows_across_a_restart(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        ana = login(lab, "ana")
        client.post("/api/rigs/twin/control", headers=ana)
        with client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws:
            ws.receive_json()
            client.post(
                "/api/rigs/twin/runs",
                headers=ana,
                json={"dt": 1, "samples": 200, "methods": ["lsm", "wlsm"]},
            )
            _, seen = receive_until(ws, "run", event="ended")
    last = max(m["seq"] for m in seen if "seq" in m)
    assert len([m for m in seen if "seq" in m]) > 400
    lab.close()
    # A new server on the same store: its numbers start above everything the old one gave.
    restarted = make_lab()
    with (
        TestClient(create_app(restarted.config, lab=restarted, sweep_interval=None)) as client,
        client.websocket_connect("/api/rigs/twin/live", headers=login(restarted, "ben")) as ws,
    ):
        assert ws.receive_json()["seq"] > last


def test_a_since_from_another_numbering_gets_the_current_run_from_the_store(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab, client, live = make(make_lab, step_clock)
    with client:
        ana = login(lab, "ana")
        client.post("/api/rigs/twin/control", headers=ana)
        run_id = client.post(
            "/api/rigs/twin/runs", headers=ana, json={"dt": 1, "samples": 100, "methods": ["lsm"]}
        ).json()["id"]
        step_clock.allow(19.0)
        until(lambda: lab.runs.record(run_id).samples_stored == 20)
        ahead = live.hub.channels["twin"].seq + 10**9  # what a server with a faster clock gave
        with client.websocket_connect(f"/api/rigs/twin/live?since={ahead}", headers=ana) as ws:
            hello = ws.receive_json()
            assert hello["seq"] < ahead
            stored = ws.receive_json()
            assert stored["type"] == "samples"
            assert [item["k"] for item in stored["items"]] == list(range(20))
        step_clock.allow(math.inf)
        lab.runs.wait("twin", timeout=30)


def test_a_stalled_socket_is_cut_over_real_tcp_and_the_others_get_everything(
    make_lab: LabFactory,
) -> None:
    """A client that stops reading: the server's writes back up, its queue fills, it is cut."""
    lab, _, _ = make(make_lab)
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    live: LiveEndpoint = app.state.live
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    config = uvicorn.Config(
        app, host="127.0.0.1", port=port, log_level="warning", ws_per_message_deflate=False
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        until(lambda: server.started)
        cookie = login(lab, "ana")["cookie"]
        url = f"ws://127.0.0.1:{port}/api/rigs/twin/live"
        channel = live.hub.channels["twin"]
        live._client_queue = 200
        stalled = socket.socket()
        stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        stalled.connect(("127.0.0.1", port))
        protocol = ClientProtocol(parse_uri(url), max_size=None)
        request = protocol.connect()
        request.headers["Cookie"] = cookie
        protocol.send_request(request)
        stalled.sendall(b"".join(protocol.data_to_send()))
        until(lambda: len(channel.clients()) == 1)  # ...and it never reads
        (stalled_client,) = channel.clients()
        live._client_queue = 100_000
        with connect(url, additional_headers={"Cookie": cookie}, max_size=None) as healthy:
            healthy.recv()  # hello
            until(lambda: len(channel.clients()) == 2)
            pad = "x" * 8000
            got: list[int] = []
            # 16 MB, more than the kernel's buffers hold, in steps of 50 messages (each
            # fits the stalled client's queue: it is cut for not draining, not for a burst).
            for k in range(2000):
                channel.publish(
                    {"type": "sample", "run": 1, "k": k, "t": k, "u": 0, "y": 0, "pad": pad}
                )
                while k % 50 == 49 and len(got) <= k:
                    frame = json.loads(healthy.recv())
                    for message in frame if isinstance(frame, list) else [frame]:
                        if message["type"] == "sample":
                            got.append(message["k"])
            assert got == list(range(2000))
            assert stalled_client.cut
            until(lambda: stalled_client not in channel.clients())  # gone before it reads
        # Reading again, it finds what had reached it, then the close frame: 4408.
        stalled.settimeout(10)
        close_code = None
        while close_code is None and (data := stalled.recv(1 << 20)):
            protocol.receive_data(data)
            for event in protocol.events_received():
                if isinstance(event, Frame) and event.opcode is Opcode.CLOSE:
                    assert protocol.close_rcvd is not None
                    close_code = protocol.close_rcvd.code
        stalled.close()
        assert close_code == 4408
    finally:
        server.should_exit = True
        thread.join(timeout=10)


def test_a_login_holds_at_most_four_live_sockets(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client, contextlib.ExitStack() as stack:
        ana = login(lab, "ana")
        for _ in range(4):
            ws = stack.enter_context(client.websocket_connect("/api/rigs/twin/live", headers=ana))
            assert receive(ws)["type"] == "hello"
        with (
            client.websocket_connect("/api/rigs/other/live", headers=ana) as ws,
            pytest.raises(WebSocketDisconnect) as info,
        ):
            ws.receive_json()
        assert info.value.code == 4429
        # Another login of the same lab is not affected.
        with client.websocket_connect("/api/rigs/twin/live", headers=login(lab, "ana")) as ws:
            assert receive(ws)["type"] == "hello"
    # Closed sockets count no more.
    with client, client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws:
        assert receive(ws)["type"] == "hello"
