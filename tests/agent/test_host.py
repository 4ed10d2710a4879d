"""The rig host alone: safe without its lab (grace, safe actuator), every sample in the outbox."""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import time
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest

from thermolab.agent.host import RigHost
from thermolab.agent.link import AgentLink, LinkSettings
from thermolab.agent.outbox import Outbox
from thermolab.agent.protocol import (
    SetChannel,
    SetGains,
    SetSetpoint,
    StartRun,
    decode_lab,
    encode,
)
from thermolab.control import PIDGains
from thermolab.errors import SetpointRangeError, ThermoLabError
from thermolab.rigs import RigSpec, make_clock
from thermolab.runner.control_request import ControlRequest


def _host(grace: float) -> RigHost:
    rig = RigSpec.parse("sim:tclab").open(clock=make_clock(1.0))
    return RigHost(rig, Outbox(":memory:"), grace=grace)


def _wait(predicate: object, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():  # type: ignore[operator]
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def test_a_lost_link_ends_the_run_after_the_grace_and_the_heater_goes_safe() -> None:
    host = _host(grace=1.0)
    try:
        host.start_run(StartRun(run=7, dt=0.05, samples=10_000, signal="const:80"))
        _wait(lambda: host.rig.powered and host.outbox.count() > 3)
        lost = time.monotonic()
        host.link_lost()
        time.sleep(0.5)
        assert host.heartbeat().run == 7  # still going within the grace
        _wait(lambda: host.heartbeat().run is None, timeout=5)
        assert time.monotonic() - lost < 1.0 + 0.5
        assert not host.rig.powered  # actuator at its safe value
        rows = host.outbox.pending(0, 10**6)
        kinds = [kind for _, kind, _ in rows]
        assert kinds[-1] == "run_ended"
        assert kinds.count("run_ended") == 1
        ks = [json.loads(body)["k"] for _, kind, body in rows if kind == "sample"]
        assert ks == list(range(len(ks)))
        assert json.loads(rows[-1][2])["reason"] == "ended"
        assert json.loads(rows[-1][2])["samples"] == len(ks)
        # The lab stores why: the lost link, not an END someone asked for.
        assert json.loads(rows[-1][2])["message"] == "link to the lab lost for over 1 s"
    finally:
        host.close()


def test_a_link_back_within_the_grace_keeps_the_run_and_an_idle_rig_goes_off_at_once() -> None:
    host = _host(grace=0.6)
    try:
        host.power(True)
        assert host.rig.powered
        host.link_lost()
        assert not host.rig.powered  # no lab: an idle rig is switched off at once
        host.start_run(StartRun(run=8, dt=0.05, samples=10_000, input=30.0))
        _wait(lambda: host.outbox.count() > 2)
        host.link_lost()
        time.sleep(0.2)
        host.link_back()
        time.sleep(0.8)
        assert host.heartbeat().run == 8  # the grace was cancelled
        host.end_run(8)
        _wait(lambda: host.heartbeat().run is None)
        assert not host.rig.powered
    finally:
        host.close()


def test_a_closed_loop_run_records_its_channels_and_takes_the_loops_commands() -> None:
    host = _host(grace=60.0)
    control = ControlRequest(setpoint=30.0, kp=4.0, ti=140.0)
    try:
        with pytest.raises(SetpointRangeError):  # checked on the host too; the link refuses it
            host.start_run(
                StartRun(run=6, dt=0.05, samples=100, control=replace(control, setpoint=500.0))
            )
        host.start_run(StartRun(run=7, dt=0.05, samples=10_000, control=control))

        def samples() -> list[dict[str, Any]]:
            rows = host.outbox.pending(0, 10**6)
            return [json.loads(body) for _, kind, body in rows if kind == "sample"]

        _wait(lambda: len(samples()) > 3, timeout=30)
        assert set(samples()[0]["extra"]) == {"r", "u_pid", "e", "auto", "fan"}
        with pytest.raises(SetpointRangeError):
            host.command(SetSetpoint(run=7, setpoint=500.0))
        with pytest.raises(ThermoLabError):
            host.command(SetSetpoint(run=8, setpoint=28.0))  # not the run going
        host.command(SetSetpoint(run=7, setpoint=28.0))
        host.command(SetGains(run=7, gains=PIDGains(5.0, 120.0)))
        _wait(lambda: samples()[-1]["extra"]["r"] == 28.0, timeout=30)
        loop = host.heartbeat().loop
        assert loop is not None
        assert loop["setpoint"] == 28.0
        _wait(lambda: host.heartbeat().loop["gains"]["Kp"] == 5.0, timeout=30)  # type: ignore[index]
        host.end_run(7)
        _wait(lambda: host.heartbeat().run is None, timeout=30)
        assert not host.rig.powered  # actuator at its safe value
        ended = json.loads(host.outbox.pending(0, 10**6)[-1][2])
        assert ended["reason"] == "ended"
        assert ended["control"]["setpoint"] == 28.0
        assert ended["control"]["gains"]["Kp"] == 5.0
    finally:
        host.close()


def test_a_kit_host_sets_heater_2_idle_and_in_its_run_and_records_t2_and_q2() -> None:
    rig = RigSpec.parse("sim:kit").open(clock=make_clock(1.0))
    host = RigHost(rig, Outbox(":memory:"), grace=5.0)
    try:
        host.power(True)
        host.set_channel("q2", 40.0, None)  # the idle rig, as a controller's PUT .../channels/q2
        assert host.rig.level("q2") == 40.0
        host.power(False)
        assert host.rig.level("q2") == 0.0  # at rest: its declared default
        host.start_run(StartRun(run=3, dt=0.05, samples=10_000, signal="const:0"))
        _wait(lambda: host.outbox.count() > 2)
        host.set_channel("q2", 70.0, 99)  # another run's: ignored
        host.command(SetChannel(run=3, name="q2", level=70.0))
        _wait(lambda: host.rig.level("q2") == 70.0)
        _wait(lambda: host.outbox.count() > 10)
        samples = [
            json.loads(body) for _, kind, body in host.outbox.pending(0, 10**6) if kind == "sample"
        ]
        assert {"t2", "q2"} <= set(samples[-1]["extra"])
        assert samples[-1]["extra"]["q2"] == 70.0
        with pytest.raises(ThermoLabError, match="no input 'fan'"):
            host.set_channel("fan", 10.0, 3)
    finally:
        host.close()
    assert host.rig.level("q2") == 0.0


def test_a_kit_host_drives_the_pair_a_start_names_and_refuses_one_the_kit_lacks() -> None:
    # A START without a pair is the frame a host of an earlier release reads: no new key.
    assert "pair" not in json.loads(encode(StartRun(run=1, dt=1.0, samples=5)))
    start = decode_lab(encode(StartRun(run=4, dt=0.05, samples=40, signal="const:30",
                                       pair=("q2", "t2"))))  # fmt: skip
    assert isinstance(start, StartRun)
    assert start.pair == ("q2", "t2")
    rig = RigSpec.parse("sim:kit").open(clock=make_clock(1.0))
    host = RigHost(rig, Outbox(":memory:"), grace=5.0)
    try:
        host.start_run(start)
        _wait(lambda: host.heartbeat().run is None and host.outbox.count() >= 41)
        samples = [
            json.loads(body) for _, kind, body in host.outbox.pending(0, 10**6) if kind == "sample"
        ]
        assert len(samples) == 40
        assert {s["u"] for s in samples} == {0.0}  # heater 1 rests
        assert {s["extra"]["q2"] for s in samples} == {30.0}  # the signal drives heater 2
        with pytest.raises(ThermoLabError, match="q3"):
            host.start_run(StartRun(run=5, dt=0.05, samples=10, pair=("q3", "t2")))
    finally:
        host.close()
    assert host.rig.level("q2") == 0.0


@contextlib.contextmanager
def _dead_address() -> Iterator[str]:
    """A loopback port nothing listens on: its machine refuses the connection (a dead worker)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    yield f"ws://127.0.0.1:{port}/api/agents/link"


@contextlib.contextmanager
def _silent_address() -> Iterator[str]:
    """A loopback port whose every new connection goes unanswered, as over a cut cable.

    A listener that never accepts, its backlog full: the kernel drops each new
    SYN, so a dial or a probe waits until it times out.
    """
    with contextlib.ExitStack() as stack:
        listener = stack.enter_context(socket.socket())
        listener.bind(("127.0.0.1", 0))
        listener.listen(0)
        port = listener.getsockname()[1]
        for _ in range(8):  # fill the accept queue; later connections find it full
            filler = stack.enter_context(socket.socket())
            filler.setblocking(False)
            with contextlib.suppress(BlockingIOError):
                filler.connect(("127.0.0.1", port))
        yield f"ws://127.0.0.1:{port}/api/agents/link"


@pytest.mark.parametrize(
    ("lab", "cause"),
    [
        # The owner worker killed, none taking over: its machine refuses the redials.
        (_dead_address, "no lab worker owned the rigs for over 1.5 s"),
        # The network away: no address answers at all.
        (_silent_address, "link to the lab lost for over 1.5 s"),
    ],
)
def test_a_run_ended_at_the_graces_end_says_whether_the_owner_or_the_link_went(
    lab: Any, cause: str
) -> None:
    """Issue #23: the stored end names the real cause (the lab stores the host's words)."""
    address = contextlib.ExitStack()
    url = address.enter_context(lab())
    host = _host(grace=1.5)
    link = AgentLink(host, LinkSettings(url=url, rig="box", secret="s", spec="sim:tclab"))

    async def dial_until_the_run_ends() -> None:
        dialling = asyncio.create_task(link.run())
        try:
            deadline = time.monotonic() + 30
            while host.heartbeat().run is not None:
                assert time.monotonic() < deadline, "the grace did not end the run"
                await asyncio.sleep(0.05)
        finally:
            dialling.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await dialling

    try:
        host.start_run(StartRun(run=9, dt=0.05, samples=10_000, signal="const:30"))
        _wait(lambda: host.outbox.count() > 2)
        host.link_lost()  # the link to the owner broke; the agent dials on
        asyncio.run(dial_until_the_run_ends())
        rows = host.outbox.pending(0, 10**6)
        assert rows[-1][1] == "run_ended"
        assert json.loads(rows[-1][2])["message"] == cause
    finally:
        host.close()
        address.close()
