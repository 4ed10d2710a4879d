"""The lab's health monitor of rig hosts, on the real link protocol (in-process lab).

A real WebSocket client (Starlette's test client) speaks the agent protocol
to the lab's ``/api/agents/link``; the lab's clock is a manual one, so a
silent host is judged without sleeping. Alerts go to a real SMTP server on
loopback (``aiosmtpd``), read back as the messages it received.
"""

from __future__ import annotations

import email
import email.policy
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from aiosmtpd.controller import Controller
from argon2 import PasswordHasher
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from thermolab.agent.protocol import (
    CLOSE_REFUSED,
    PROTOCOL_VERSION,
    Ack,
    Heartbeat,
    Hello,
    Power,
    RunEnded,
    SampleBatch,
    SampleOut,
    Welcome,
    decode_lab,
    encode,
)
from thermolab.lab.accounts.users import Principal
from thermolab.lab.agents import issue_secret
from thermolab.lab.agents.notify import Mailer
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import RigConfig, default_config
from thermolab.lab.http.app import create_app
from thermolab.lab.runs.request import RunRequest
from thermolab.lab.service import Lab

from .fleet import free_port

FAST_HASHER = PasswordHasher(time_cost=1, memory_cost=8, parallelism=1)


class _Inbox:
    def __init__(self) -> None:
        self.messages: list[str] = []

    async def handle_DATA(self, server: Any, session: Any, envelope: Any) -> str:  # noqa: N802
        self.messages.append(envelope.content.decode())
        return "250 OK"


@pytest.fixture
def inbox() -> Iterator[tuple[_Inbox, int]]:
    handler = _Inbox()
    port = free_port()
    controller = Controller(handler, hostname="127.0.0.1", port=port)
    controller.start()
    try:
        yield handler, port
    finally:
        controller.stop()


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[Lab]:
    config = default_config(tmp_path)
    config = replace(config, rigs=(RigConfig("box", "Remote box", "sim:tclab", agent=True),))
    the_lab = Lab(config, clock=ManualClock(), hasher=FAST_HASHER)
    the_lab.start()
    yield the_lab
    the_lab.close()


def _hello(secret: str, host: str = "") -> str:
    """The first message of a host of ``box`` (``host``: which process, Hello.host)."""
    hello = Hello(
        rig="box",
        secret=secret,
        protocol=PROTOCOL_VERSION,
        version="t",
        spec="sim:tclab",
        host=host,
    )
    return encode(hello)


def _closed(ws: Any) -> WebSocketDisconnect:
    """How the lab closed a host's link (read past what it sent before: Power, SetFan...)."""
    for _ in range(100):
        try:
            ws.receive_text()
        except WebSocketDisconnect as exc:
            return exc
    raise AssertionError("the link stayed open")


def _wait(predicate: Any, timeout: float = 10) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def test_health_faults_and_heals_the_rig_and_mails_the_teachers(
    lab: Lab, inbox: tuple[_Inbox, int]
) -> None:
    handler, port = inbox
    lab.agents.notify = Mailer("127.0.0.1", port, ("teachers@example.org",))
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    secret = issue_secret(lab.db, lab.config, clock, "box")
    assert lab.access.snapshot("box").fault == "rig host: offline (not connected)"
    app = create_app(lab.config, lab=lab, close_lab=False, sweep_interval=None)
    with TestClient(app) as client, client.websocket_connect("/api/agents/link") as ws:
        ws.send_text(_hello(secret))
        assert isinstance(decode_lab(ws.receive_text()), Welcome)
        _wait(lambda: lab.access.snapshot("box").fault is None)  # healed by itself
        # A reading over the kit's 90 degC limit: out of service, and back when it cools.
        ws.send_text(encode(Heartbeat(powered=True, u=0.0, y=95.0, pending=0)))
        _wait(lambda: lab.agents._status["box"].y == 95.0)
        lab.sweep()
        assert "outside the rig's safe range" in str(lab.access.snapshot("box").fault)
        ws.send_text(encode(Heartbeat(powered=True, u=0.0, y=40.0, pending=0)))
        _wait(lambda: lab.agents._status["box"].y == 40.0)
        lab.sweep()
        assert lab.access.snapshot("box").fault is None
        # A fault the host reports.
        ws.send_text(encode(Heartbeat(powered=False, y=40.0, fault="sensor open", pending=0)))
        _wait(lambda: lab.agents._status["box"].fault == "sensor open")
        lab.sweep()
        assert "sensor open" in str(lab.access.snapshot("box").fault)
        ws.send_text(encode(Heartbeat(powered=False, y=40.0, pending=0)))
        _wait(lambda: lab.agents._status["box"].fault is None)
        lab.sweep()
        assert lab.access.snapshot("box").fault is None
        # Samples of an unknown run are ignored but acknowledged (idempotent store).
        batch = SampleBatch(
            samples=[SampleOut(seq=7, run=99, k=0, t=0, u=0, y=20, t_read=0, jitter=0, lateness=0)]
        )
        ws.send_text(encode(batch))
        answer = decode_lab(ws.receive_text())
        while isinstance(answer, Power):  # the lab may tell the rig's power first
            answer = decode_lab(ws.receive_text())
        assert answer == Ack(seq=7)
        # Silence: the host is dropped and the rig taken out of service.
        clock.advance(lab.agents.grace + 1)
        lab.sweep()
        assert "stopped answering" in str(lab.access.snapshot("box").fault)
    _wait(lambda: len(handler.messages) >= 6)  # back, range, back, fault, back, silent
    subjects = [
        str(email.message_from_string(m, policy=email.policy.default)["Subject"])
        for m in handler.messages
    ]
    assert any("outside the rig's safe range" in s for s in subjects), subjects
    assert any("back in service" in s for s in subjects), subjects
    assert any("stopped answering" in s for s in subjects), subjects


def test_a_wrong_secret_or_a_rotated_one_is_refused(lab: Lab) -> None:
    old = issue_secret(lab.db, lab.config, lab.clock, "box")
    new = issue_secret(lab.db, lab.config, lab.clock, "box")  # rotation
    app = create_app(lab.config, lab=lab, close_lab=False, sweep_interval=None)
    with TestClient(app) as client:
        for secret in (old, "x" * 43):
            with client.websocket_connect("/api/agents/link") as ws:
                ws.send_text(_hello(secret))
                with pytest.raises(WebSocketDisconnect) as closed:
                    ws.receive_text()
                assert closed.value.code == CLOSE_REFUSED
        with client.websocket_connect("/api/agents/link") as ws:
            ws.send_text(_hello(new))
            assert isinstance(decode_lab(ws.receive_text()), Welcome)
            assert lab.agents.online("box")
        _wait(lambda: not lab.agents.online("box"))  # gone with its socket


def _beating(lab: Lab, who: Principal, seconds: float) -> None:
    """Let ``seconds`` pass on the lab's clock, ``who``'s page beating meanwhile; sweep."""
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    left = seconds
    while left > 0:
        step = min(5.0, left)
        clock.advance(step)
        left -= step
        lab.access.heartbeat("box", who)
    lab.sweep()


def test_a_host_that_redials_within_the_timeout_keeps_the_rig_and_the_turn(lab: Lab) -> None:
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    secret = issue_secret(lab.db, lab.config, clock, "box")
    info = lab.users.add("ana", "correct horse battery", "student")
    ana = Principal(info.id, info.username, info.role)
    app = create_app(lab.config, lab=lab, close_lab=False, sweep_interval=None)
    with TestClient(app) as client:
        with client.websocket_connect("/api/agents/link") as ws:
            ws.send_text(_hello(secret))
            assert isinstance(decode_lab(ws.receive_text()), Welcome)
            _wait(lambda: lab.access.snapshot("box").fault is None)
            lab.access.request_control("box", ana)
        # The link closed: offline at once, but the rig stays in service for the timeout.
        _wait(lambda: not lab.agents.online("box"))
        _beating(lab, ana, lab.agents.grace - 1)
        assert lab.access.snapshot("box").fault is None
        with client.websocket_connect("/api/agents/link") as ws:  # the host redials
            ws.send_text(_hello(secret))
            assert isinstance(decode_lab(ws.receive_text()), Welcome)
            _wait(lambda: lab.agents.online("box"))
            _beating(lab, ana, 2.0)  # past the first loss's timeout: it no longer counts
            assert lab.access.snapshot("box").fault is None
            controller = lab.access.snapshot("box").controller
            assert controller is not None
            assert controller.user_id == ana.user_id
        # Away for longer than a silent host may be: out of service, the turn ended.
        _wait(lambda: not lab.agents.online("box"))
        clock.advance(lab.agents.grace + 1)
        lab.sweep()
        assert lab.access.snapshot("box").fault == "rig host: offline (not connected)"
        assert lab.access.snapshot("box").controller is None


def test_a_cut_cable_inside_the_grace_keeps_the_turn_and_past_it_ends_it(lab: Lab) -> None:
    """One rule: the lab keeps the rig in service as long as the host keeps its run."""
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    secret = issue_secret(lab.db, lab.config, clock, "box")
    info = lab.users.add("ana", "correct horse battery", "student")
    ana = Principal(info.id, info.username, info.role)
    app = create_app(lab.config, lab=lab, close_lab=False, sweep_interval=None)
    with TestClient(app) as client, client.websocket_connect("/api/agents/link") as ws:
        ws.send_text(_hello(secret))
        assert isinstance(decode_lab(ws.receive_text()), Welcome)
        _wait(lambda: lab.access.snapshot("box").fault is None)
        lab.access.request_control("box", ana)
        # The cable cut: the link stays open and silent. 20 s is more than the silence
        # that dropped a turn before (5 s), and inside the host's grace.
        _beating(lab, ana, 20.0)
        _wait(lambda: not lab.agents.online("box"))  # offline: its silent link dropped
        lab.sweep()
        snapshot = lab.access.snapshot("box")
        assert snapshot.fault is None
        assert snapshot.controller is not None
        assert snapshot.controller.user_id == ana.user_id
        # Past the grace the host has ENDed its run: out of service, the turn over.
        clock.advance(lab.agents.grace - 20.0 + 1)
        lab.sweep()
        assert lab.access.snapshot("box").fault == "rig host: offline (not connected)"
        assert lab.access.snapshot("box").controller is None


def test_a_second_host_for_a_linked_rig_is_refused_and_the_same_one_redials(
    lab: Lab, caplog: pytest.LogCaptureFixture
) -> None:
    secret = issue_secret(lab.db, lab.config, lab.clock, "box")
    app = create_app(lab.config, lab=lab, close_lab=False, sweep_interval=None)
    with TestClient(app) as client, client.websocket_connect("/api/agents/link") as first:
        first.send_text(_hello(secret, "bench-1:100:aa"))
        assert isinstance(decode_lab(first.receive_text()), Welcome)
        # Another machine with the same secret (a copied config): refused, said and logged.
        with client.websocket_connect("/api/agents/link") as second:
            second.send_text(_hello(secret, "bench-2:200:bb"))
            refused = _closed(second)
        assert refused.code == CLOSE_REFUSED
        assert "served by another host (bench-1)" in refused.reason
        assert "one host per rig" in refused.reason
        assert any("refused a second host" in r.getMessage() for r in caplog.records)
        assert lab.agents.online("box")
        # The first host's own redial (its old link half-open) replaces its link.
        with client.websocket_connect("/api/agents/link") as again:
            again.send_text(_hello(secret, "bench-1:100:aa"))
            assert isinstance(decode_lab(again.receive_text()), Welcome)
            assert _closed(first).reason == "replaced or silent"


def test_a_rotated_secret_drops_the_link_made_with_the_old_one(lab: Lab) -> None:
    old = issue_secret(lab.db, lab.config, lab.clock, "box")
    app = create_app(lab.config, lab=lab, close_lab=False, sweep_interval=None)
    with TestClient(app) as client, client.websocket_connect("/api/agents/link") as ws:
        ws.send_text(_hello(old, "bench-1:100:aa"))
        assert isinstance(decode_lab(ws.receive_text()), Welcome)
        lab.sweep()
        assert lab.agents.online("box")  # the secret still holds: nothing happens
        issue_secret(lab.db, lab.config, lab.clock, "box")  # rotated (thermolab agent secret)
        lab.sweep()
        _wait(lambda: not lab.agents.online("box"))  # fails in 10 s, rather than hang below
        assert _closed(ws).reason == "replaced or silent"


@pytest.mark.parametrize(
    ("message", "stored"),
    [
        # The host's grace ran out first: it ENDed the run itself and says why — no
        # address of the lab answered (the link lost) ...
        (
            "link to the lab lost for over 30 s",
            "link_lost: link to the lab lost for over 30 s",
        ),
        # ... or the lab's machines answered and no worker owned the rigs (the owner gone).
        (
            "no lab worker owned the rigs for over 30 s",
            "owner_gone: no lab worker owned the rigs for over 30 s",
        ),
        # The host came back in time to hear the END the lab sent when its turn ended.
        ("ended by request", "host_away: offline (not connected)"),
    ],
)
def test_a_run_ended_by_its_hosts_absence_says_so(lab: Lab, message: str, stored: str) -> None:
    """The stored end names the real cause, never "the end of the turn" alone."""
    secret = issue_secret(lab.db, lab.config, lab.clock, "box")
    info = lab.users.add("ana", "correct horse battery", "student")
    ana = Principal(info.id, info.username, info.role)
    app = create_app(lab.config, lab=lab, close_lab=False, sweep_interval=None)
    with TestClient(app) as client:
        with client.websocket_connect("/api/agents/link") as ws:
            ws.send_text(_hello(secret))
            assert isinstance(decode_lab(ws.receive_text()), Welcome)
            _wait(lambda: lab.access.snapshot("box").fault is None)
            lab.access.request_control("box", ana)
            request = RunRequest(dt=1.0, samples=100, signal="step:0:10@1", methods=("srm",))
            run_id = lab.remote_runs.start("box", ana, request).id
        _wait(lambda: not lab.agents.online("box"))
        _beating(lab, ana, lab.agents.grace + 1)  # away past its grace: the turn ends
        assert lab.access.snapshot("box").controller is None
        lab.agents.on_run_ended(
            "box", RunEnded(seq=1, run=run_id, reason="ended", message=message, samples=0)
        )
    record = lab.runs.record(run_id)
    assert (record.status, record.end_reason) == ("stopped", stored)
