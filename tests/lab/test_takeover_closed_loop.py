"""A rig host's closed-loop (PID) run lives through the owner worker's death.

As tests/lab/test_takeover_agents.py (its owner, standby and host, real
processes on PostgreSQL and Redis), but the run is a closed loop driven by the
host's runner (tests/agent/test_closed_loop.py): ana starts it with the set
point 35 through the standby, the owner is killed with SIGKILL mid-run, the
standby takes over. Then the same student still controls, the loop state
route and the run's record answer on the new owner (the host's heartbeats), a set-point change
through it reaches the host and shows in the stored ``r``, and the run goes on
to its last sample on the host: its end is stored with its controller, its
method results and its timing, every sample with the control channels, and the rig is left
at its safe input. Skipped, with the reason, where PostgreSQL or Redis is absent.
"""

from __future__ import annotations

import math
import signal
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from thermolab.lab.db import Database

from .test_takeover import TAKEN_OVER, _open_turns
from .test_takeover_agents import hosts_online, owner_standby_and_host, wait_for
from .test_workers import Worker

pytestmark = [pytest.mark.postgres, pytest.mark.redis, pytest.mark.slow]

SPEEDUP = 80.0
"""The host's twin, 80 times real time: the run's 3000 samples (1 s apart) last 38 s. The
takeover and the checks before the end took 6 s on an idle machine (the set point 30
reached the host at sample 249 at 40x), so the run outlasts them threefold under load."""
SAMPLES = 3000
KP, TI = 4.0, 140.0  # as tests/agent/test_closed_loop.py: SIMC on the kit twin
LOOP_CHANNELS = ("r", "u_pid", "e", "auto")


@pytest.fixture
def lab(
    tmp_path: Path, postgres_url: str, redis_url: str
) -> Iterator[tuple[Worker, Worker, dict[str, str], Database]]:
    with owner_standby_and_host(tmp_path, postgres_url, redis_url, speedup=SPEEDUP) as made:
        yield made


def _samples(http: httpx.Client, run_id: int) -> dict[str, list[Any]]:
    answer = http.get(f"/api/runs/{run_id}/export.json")
    assert answer.status_code == 200, answer.text
    samples: dict[str, list[Any]] = answer.json()["samples"]
    return samples


def _loop(http: httpx.Client) -> dict[str, Any] | None:
    answer = http.get("/api/rigs/box/loop")
    assert answer.status_code == 200, answer.text
    loop: dict[str, Any] | None = answer.json()["loop"]
    return loop


def _here(http: httpx.Client, check: Callable[[], Any]) -> Callable[[], Any]:
    """``check``, after the controller's heartbeat (a turn ends 15 s, ``client_timeout``,
    after the last; the live socket or polling page of a browser sends them)."""

    def checked() -> Any:
        http.post("/api/rigs/box/heartbeat")
        return check()

    return checked


def _box(teacher: httpx.Client) -> dict[str, Any]:
    hosts: list[dict[str, Any]] = teacher.get("/api/agents").json()
    return next(h for h in hosts if h["rig"] == "box")


def test_a_rig_hosts_closed_loop_run_goes_on_to_its_end_under_the_standby(
    lab: tuple[Worker, Worker, dict[str, str], Database], tmp_path: Path
) -> None:
    owner, standby, cookies, db = lab
    wait_for("the agent links to the owner", lambda: hosts_online(standby, cookies["tina"]))
    with (
        httpx.Client(base_url=standby.base, headers={"Cookie": cookies["ana"]}, timeout=30) as ana,
        httpx.Client(
            base_url=standby.base, headers={"Cookie": cookies["tina"]}, timeout=30
        ) as teacher,
    ):
        wait_for(  # 409 while the health check has the rig out of service
            "ana takes the box", lambda: ana.post("/api/rigs/box/control").status_code == 200
        )
        started = ana.post(
            "/api/rigs/box/runs",
            json={
                "dt": 1.0,
                "samples": SAMPLES,
                "methods": ["lsm"],
                "control": {"setpoint": 35.0, "kp": KP, "ti": TI},
            },
        )
        assert started.status_code == 201, started.text
        run_id: int = started.json()["id"]
        (turn,) = _open_turns(db)
        wait_for("samples are stored", _here(ana, lambda: len(_samples(ana, run_id)["k"]) >= 20))
        # A set-point change before the takeover: the new owner must know it too.
        changed = ana.put("/api/rigs/box/runs/current/setpoint", json={"setpoint": 33.0})
        assert changed.status_code == 200, changed.text
        wait_for("the set point 33 stored", _here(ana, lambda: 33.0 in _samples(ana, run_id)["r"]))

        owner.process.send_signal(signal.SIGKILL)
        owner.process.wait()
        # What the loop route tells from the kill until the host's heartbeats reach the
        # new owner (a follower forwards the route to the owner: 503 while there is none).
        told: list[float] = []

        def taken_over() -> bool:
            answer = ana.get("/api/rigs/box/loop")
            if answer.status_code == 200 and (loop := answer.json()["loop"]) is not None:
                told.append(loop["setpoint"])
            return TAKEN_OVER in standby.log.read_text() and hosts_online(standby, cookies["tina"])

        wait_for("the standby takes over, the host linked to it", taken_over)
        assert "linked to " + standby.ws in (tmp_path / "agent.log").read_text()
        assert told, "the loop route never answered"
        assert set(told) == {33.0}, told
        # The same student controls, in the same turn.
        assert ana.get("/api/rigs/box").json()["access"]["role"] == "controller"
        assert _open_turns(db) == [turn]
        # The new owner tells the host's loop, as its heartbeats have it.
        loop = wait_for(
            "the host's loop state on the new owner",
            lambda: (state := _loop(ana)) is not None and "mode" in state and state,
        )
        assert loop["run"] == run_id
        assert loop["mode"] == "auto"
        assert loop["setpoint"] == 33.0
        # ... and so does the run's record, in the shape of an in-process run's.
        control = ana.get(f"/api/runs/{run_id}").json()["control"]
        assert control.keys() == loop.keys() - {"run"}
        assert (control["mode"], control["setpoint"], control["gains"]) == (
            "auto",
            33.0,
            loop["gains"],
        )

        # A set-point change through the new owner reaches the host.
        changed = ana.put("/api/rigs/box/runs/current/setpoint", json={"setpoint": 30.0})
        assert changed.status_code == 200, changed.text
        wait_for(
            "the host's new set point",
            lambda: (state := _loop(ana)) is not None and state["setpoint"] == 30.0,
        )
        wait_for("the new set point stored", _here(ana, lambda: 30.0 in _samples(ana, run_id)["r"]))
        assert ana.get(f"/api/runs/{run_id}").json()["control"]["setpoint"] == 30.0

        record = wait_for(
            "the run's end on the host, stored",
            _here(
                ana,
                lambda: (r := ana.get(f"/api/runs/{run_id}").json())["status"] != "running" and r,
            ),
            timeout=SAMPLES / SPEEDUP + 120,
        )
        assert record["status"] == "finished", (record["endReason"], record["samplesStored"])
        assert record["control"]["mode"] == "auto"
        assert record["control"]["setpoint"] == 30.0
        # Its timing, judged by the new owner on every stored sample (a twin: exact).
        timing = record["timing"]
        assert timing is not None, record
        assert (timing["rig"], timing["maxLateness"], timing["warnings"]) == ("twin", None, [])
        # Its identifiers, built again by the new owner from what was stored before.
        assert "lsm" in record["results"], record
        rows = _samples(ana, run_id)
        ks = [int(k) for k in rows["k"]]
        assert ks == list(range(SAMPLES)), "a sample is missing or doubled"
        assert record["samplesStored"] == SAMPLES
        for name in LOOP_CHANNELS:
            assert all(v is not None for v in rows[name]), f"{name} missing in a sample"
        r, y, e = rows["r"], rows["y"], rows["e"]
        first_33, first_30 = r.index(33.0), r.index(30.0)
        assert set(r[:first_33]) == {35.0}
        assert set(r[first_33:first_30]) == {33.0}
        assert set(r[first_30:]) == {30.0}
        assert all(
            math.isclose(ei, ri - yi, abs_tol=1e-9) for ei, ri, yi in zip(e, r, y, strict=True)
        )
        assert set(rows["auto"]) == {1.0}
        # The run's end left the rig safe: the host's runner powered it off (or the idle
        # rig rests at its safe input, 0 %).
        wait_for(
            "the host idle and safe",
            lambda: (box := _box(teacher))["powered"] is False or box["u"] == 0.0,
        )
