"""A rig on a rig host is handed over clean (issue #23), end to end: a TLS lab and an agent.

The in-process property (tests/lab/test_handover.py) through a real ``thermolab
agent``: a controller's idle heater and a closed loop's fan at 50 % do not
reach the next user after a teacher's kick. The host's twin (the kit's, 20
times real time) rests at its declared defaults and the next closed-loop run
records its fan at the declared 0 % from its first sample; the rig the browser
gets shows the host's fan as its run's samples and its rests tell it.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from .fleet import ONE_REMOTE_BOX, PASSWORD, Fleet, make_fleet, thermolab

pytestmark = pytest.mark.slow

CLOSED_LOOP = {"setpoint": 35.0, "kp": 4.0, "ti": 140.0}


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[Fleet]:
    made = make_fleet(tmp_path, ONE_REMOTE_BOX)
    for name in ("ben", "carla"):
        thermolab(
            tmp_path, "user", "add", name, "--role", "student", "--password-stdin",
            "--config", str(made.config), stdin=PASSWORD + "\n",
        )  # fmt: skip
    try:
        made.start_lab(made.cert, made.key, grace=30.0)  # type: ignore[attr-defined]
        yield made
    finally:
        made.stop()


def _until(what: str, check: Callable[[], Any], timeout: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        found = check()
        if found:
            return found
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.2)


def _fan_shown(client: Any) -> float | None:
    actuators = client.get("/api/rigs/box").json()["actuators"]
    assert [(a["name"], a["default"]) for a in actuators] == [("fan", 0.0)]
    level: float | None = actuators[0]["level"]
    return level


def test_a_kick_hands_the_next_user_a_host_rig_at_its_declared_defaults(fleet: Fleet) -> None:
    fleet.start_agent("box", "sim:tclab", speedup=20.0)
    with contextlib.ExitStack() as stack:
        tina, ana, ben, carla = (
            stack.enter_context(contextlib.closing(fleet.client(n)))
            for n in ("tina", "ana", "ben", "carla")
        )
        fleet.wait_online(tina, "box")
        # 1. An idle heater: ana's 80 % must not be ben's after the kick.
        assert ana.post("/api/rigs/box/control").json()["access"]["role"] == "controller"
        assert ben.post("/api/rigs/box/control").json()["access"]["role"] == "queued"
        assert ana.put("/api/rigs/box/input", json={"u": 80.0}).status_code == 200
        _until("ana's heater on the host", lambda: fleet.host(tina, "box")["u"] == 80.0)
        assert tina.post("/api/rigs/box/control/kick").status_code == 200
        assert ben.get("/api/rigs/box").json()["access"]["role"] == "controller"
        _until("the host at its safe input", lambda: fleet.host(tina, "box")["u"] == 0.0)
        time.sleep(2.5)  # two heartbeats later, nothing sent it back
        assert fleet.host(tina, "box")["u"] == 0.0
        # 2. A closed loop's fan: ben's 50 % must not be carla's after the kick.
        assert carla.post("/api/rigs/box/control").json()["access"]["role"] == "queued"
        body = {"dt": 1.0, "samples": 3000, "methods": ["lsm"], "control": CLOSED_LOOP}
        answer = ben.post("/api/rigs/box/runs", json=body)
        assert answer.status_code == 201, answer.text
        run_id = answer.json()["id"]
        _until("the host's loop", lambda: ben.get("/api/rigs/box/loop").json()["loop"])
        fan = ben.put("/api/rigs/box/runs/current/fan", json={"percent": 50.0})
        assert fan.status_code == 200, fan.text

        def fan_stored() -> bool:
            stored = ben.get(f"/api/runs/{run_id}/export.json").json()["samples"]
            return 50.0 in (stored.get("fan") or [])

        _until("the fan on in ben's run", fan_stored)
        # The rig as the browser gets it shows the host's fan, from the run's samples...
        assert _fan_shown(ben) == 50.0
        assert tina.post("/api/rigs/box/control/kick").status_code == 200
        _until("ben's run ended", lambda: tina.get(f"/api/runs/{run_id}").json()["endedAt"])
        role = lambda: carla.get("/api/rigs/box").json()["access"]["role"]  # noqa: E731
        _until("carla at the controls", lambda: role() == "controller")
        assert _fan_shown(carla) == 0.0  # ... and at its declared default once handed over
        answer = carla.post("/api/rigs/box/runs", json={**body, "samples": 5})
        assert answer.status_code == 201, answer.text
        carla_run = answer.json()["id"]
        _until("carla's run ended", lambda: carla.get(f"/api/runs/{carla_run}").json()["endedAt"])
        stored = carla.get(f"/api/runs/{carla_run}/export.json").json()["samples"]
        assert stored["fan"]
        assert set(stored["fan"]) == {0.0}
