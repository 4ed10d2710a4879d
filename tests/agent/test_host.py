"""The rig host alone: safe without its lab (grace, safe actuator), every sample in the outbox."""

from __future__ import annotations

import json
import time

from thermolab.agent.host import RigHost
from thermolab.agent.outbox import Outbox
from thermolab.agent.protocol import StartRun
from thermolab.rigs import RigSpec, make_clock


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
