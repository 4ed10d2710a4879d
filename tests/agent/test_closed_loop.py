"""A closed-loop (PID) run on a remote rig, end to end: a TLS lab and a ``thermolab agent``.

The host's runner drives the PID on its twin (20 times real time): the run
reaches its set point, a set-point change goes through the lab to the host
and shows in the stored ``r`` channel, END leaves the actuator safe and
stores the controller's end as an in-process run does; the run's record shows
the loop live (the host's heartbeat) and, at the end, the run's timing. A second run: the
lab paused mid-run (the link cut, as tests/agent/test_fleet.py cuts it)
does not stop the loop (the grace is longer than the cut), and every sample
taken meanwhile, control channels included, is stored after the link is back.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from .fleet import ONE_REMOTE_BOX, Fleet, make_fleet

pytestmark = pytest.mark.slow

GRACE = 120.0  # longer than the cut: the run must go on through it
SPEEDUP = 20.0
KP, TI = 4.0, 140.0  # SIMC on the kit twin's FOPDT (0.6, 140 s, 16 s), tau_c ~ 40 s


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[Fleet]:
    made = make_fleet(tmp_path, ONE_REMOTE_BOX)
    try:
        made.start_lab(made.cert, made.key, grace=GRACE)  # type: ignore[attr-defined]
        yield made
    finally:
        made.stop()


def _samples(client: httpx.Client, run_id: int) -> dict[str, list[Any]]:
    answer = client.get(f"/api/runs/{run_id}/export.json")
    assert answer.status_code == 200, answer.text
    samples: dict[str, list[Any]] = answer.json()["samples"]
    return samples


def _until(what: str, check: Callable[[], Any], timeout: float = 120.0) -> Any:
    """Poll ``check`` until it returns something truthy (a deadline, never a bare sleep)."""
    deadline = time.monotonic() + timeout
    while True:
        found = check()
        if found:
            return found
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.5)


def _settled(client: httpx.Client, run_id: int, setpoint: float, after: int = 0) -> bool:
    """The stored ``y`` has stayed within 1 degC of ``setpoint`` for its last 30 samples."""
    client.post("/api/rigs/box/heartbeat")  # the controller is there: its turn goes on
    rows = _samples(client, run_id)
    ys = rows["y"][after:]
    return len(ys) >= 30 and all(abs(y - setpoint) < 1.0 for y in ys[-30:])


def test_a_closed_loop_run_on_a_rig_host_tracks_commands_and_outlives_a_cut_link(
    fleet: Fleet,
) -> None:
    agent = fleet.start_agent("box", "sim:tclab", speedup=SPEEDUP)
    with (
        contextlib.closing(fleet.client("tina")) as teacher,
        contextlib.closing(fleet.client("ana")) as ana,
    ):
        fleet.wait_online(teacher, "box")
        # The host said its pace when it dialled in: the lab publishes it.
        assert teacher.get("/api/rigs/box").json()["speedup"] == SPEEDUP
        assert ana.post("/api/rigs/box/control").json()["access"]["role"] == "controller"
        # The loop's commands need a closed-loop run, as in-process.
        answer = ana.put("/api/rigs/box/runs/current/setpoint", json={"setpoint": 30.0})
        assert answer.status_code == 409, answer.text
        assert answer.json()["code"] == "no_run"
        # A set point the rig cannot reach is refused as in-process, before anything starts.
        refused = ana.post(
            "/api/rigs/box/runs",
            json={"dt": 1.0, "samples": 50, "control": {"setpoint": 500.0, "kp": KP, "ti": TI}},
        )
        assert refused.status_code == 422, refused.text
        assert refused.json()["code"] == "setpoint_out_of_range"
        run = ana.post(
            "/api/rigs/box/runs",
            json={
                "dt": 1.0,
                "samples": 3000,
                "methods": ["lsm"],
                "control": {"setpoint": 35.0, "kp": KP, "ti": TI},
            },
        )
        assert run.status_code == 201, run.text
        run_id = run.json()["id"]
        # The run's record shows its loop from the start, as an in-process run's does.
        started = run.json()["control"]
        assert (started["mode"], started["setpoint"], started["gains"]["Kp"]) == ("auto", 35.0, KP)
        # The host's loop, as its heartbeat tells it.
        loop = _until(
            "the host's loop state",
            lambda: ana.get("/api/rigs/box/loop").json()["loop"],
        )
        assert loop["run"] == run_id
        assert loop["mode"] == "auto"
        assert loop["setpoint"] == 35.0
        live = ana.get(f"/api/runs/{run_id}").json()
        assert live["status"] == "running"
        assert live["control"].keys() == loop.keys() - {"run"}  # the same loop, the same shape
        assert (live["control"]["mode"], live["control"]["setpoint"]) == ("auto", 35.0)
        assert live["timing"] is None  # judged at the end, as in-process

        _until("the set point 35", lambda: _settled(ana, run_id, 35.0))

        # Bad commands are refused with the in-process codes; a good one reaches the host.
        url = "/api/rigs/box/runs/current"
        answer = ana.put(f"{url}/setpoint", json={"setpoint": 500.0})
        assert answer.status_code == 422, answer.text
        assert answer.json()["code"] == "setpoint_out_of_range"
        answer = ana.put(f"{url}/gains", json={"kp": 1e9, "ti": TI})
        assert answer.status_code == 422, answer.text
        assert answer.json()["code"] == "gain_out_of_range"
        answer = ana.put(f"{url}/setpoint", json={"setpoint": 30.0})
        assert answer.status_code == 200, answer.text
        changed_at = len(_samples(ana, run_id)["k"])
        _until(
            "the host's new set point",
            lambda: ana.get("/api/rigs/box/loop").json()["loop"]["setpoint"] == 30.0,
        )
        # ... and the run's record with it (the host's heartbeat, not the lab's copy).
        _until(
            "the record's new set point",
            lambda: ana.get(f"/api/runs/{run_id}").json()["control"]["setpoint"] == 30.0,
        )

        _until("the set point 30", lambda: _settled(ana, run_id, 30.0, after=changed_at))
        answer = ana.post(f"{url}/stop")
        assert answer.status_code == 200, answer.text
        record = _until(
            "the run's end",
            lambda: (r := ana.get(f"/api/runs/{run_id}").json())["status"] != "running" and r,
        )
        assert record["status"] == "stopped", record
        assert record["endReason"] == "ended by ana"
        # The controller's end, stored as an in-process closed-loop run's.
        assert record["control"]["mode"] == "auto"
        assert record["control"]["setpoint"] == 30.0
        assert record["control"]["gains"]["Kp"] == KP
        # Its timing, stored as an in-process run's end stores it: the twin's data are
        # exact (timed by its own clock, so no lateness), its period does not spread.
        timing = record["timing"]
        assert timing.keys() == {"rig", "maxLateness", "p95Lateness", "periodSpread", "warnings"}
        assert (timing["rig"], timing["maxLateness"], timing["p95Lateness"]) == ("twin", None, None)
        assert 0.0 <= timing["periodSpread"] < 0.01
        assert timing["warnings"] == []
        names = [c["name"] for c in record["channels"]]
        assert names[-5:] == ["r", "u_pid", "e", "auto", "fan"]

        rows = _samples(ana, run_id)
        ks = [int(k) for k in rows["k"]]
        assert ks == list(range(len(ks))), "a sample is missing or doubled"
        assert record["samplesStored"] == len(ks)
        assert 0 < len(ks) < 3000  # ENDed, not run to its end
        r, y, e = rows["r"], rows["y"], rows["e"]
        assert all(v is not None for v in (*r, *e, *rows["auto"]))
        assert r[0] == 35.0
        assert r[-1] == 30.0
        assert set(r) == {35.0, 30.0}
        first_30 = r.index(30.0)
        assert all(v == 35.0 for v in r[:first_30])
        assert all(v == 30.0 for v in r[first_30:])
        assert all(
            math.isclose(ei, ri - yi, abs_tol=1e-9) for ei, ri, yi in zip(e, r, y, strict=True)
        )
        assert set(rows["auto"]) == {1.0}
        # END left the actuator safe: the host's run powered the rig off (or the lab's
        # idle rig rests at its safe input).
        _until("the host idle and safe", lambda: _safe(fleet.host(teacher, "box")))

        # A second run, and the link cut mid-run: the host's loop goes on without the lab.
        run = ana.post(
            "/api/rigs/box/runs",
            json={"dt": 1.0, "samples": 3000, "control": {"setpoint": 30.0, "kp": KP, "ti": TI}},
        )
        assert run.status_code == 201, run.text
        run_id = run.json()["id"]
        _until("the set point 30", lambda: _settled(ana, run_id, 30.0))
        before_cut = len(_samples(ana, run_id)["k"])
        fleet.pause_lab()
        time.sleep(8.0)  # the lab frozen: the host notices (pings) and samples on
        fleet.resume_lab()
        fleet.wait_online(teacher, "box")
        # The lab faults a host that fell silent, which ends the turn and so the run
        # (its health rules, docs/fleet.md); else its controller ENDs it.
        if ana.get(f"/api/runs/{run_id}").json()["status"] == "running":
            ana.post(f"{url}/stop")  # 403 if the turn has just ended: the run ENDs anyway
        record = _until(
            "the second run's end",
            lambda: (r := ana.get(f"/api/runs/{run_id}").json())["status"] != "running" and r,
        )
        assert record["status"] == "stopped", record
        assert record["control"]["setpoint"] == 30.0
        rows = _samples(ana, run_id)
        ks = [int(k) for k in rows["k"]]
        assert ks == list(range(len(ks))), "a sample is missing or doubled"
        # The cut lasted ~160 samples at 20x: taken on the host, uploaded after it.
        assert len(ks) > before_cut + 100
        cut = slice(before_cut + 40, before_cut + 140)  # well inside the cut
        assert all(v == 30.0 for v in rows["r"][cut])
        assert all(v == 1.0 for v in rows["auto"][cut])
        # The loop kept the box at its set point (a rig left off would cool by degrees).
        assert all(abs(v - 30.0) < 1.0 for v in rows["y"][cut])
        assert all(v > 0.0 for v in rows["u"][cut])
        _until("the host idle and safe", lambda: _safe(fleet.host(teacher, "box")))
        assert agent.poll() is None


def _safe(host: dict[str, Any]) -> bool:
    """No run on the host and its heater off (or the idle rig at its safe input, 0 %)."""
    return host["powered"] is False or host["u"] == 0.0
