"""A run on a kit hosted by a rig host identifies the pair the student chose (issue #22).

The in-process case is tests/lab/test_kit_pair.py; here the same START, with
``input: "q2"``, ``output: "t2"``, goes to a real TLS lab (``thermolab serve``)
and one ``thermolab agent`` on the kit's twin (``sim:kit``, 100 times real
time). The host's runner steps heater 2 (heater 1 rests), and the lab feeds its
methods sensor 2's answer from the samples the host sends, judges the models on
that pair's columns of the stored record and states the results in the pair's
units, as an in-process run does.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from .fleet import Fleet, make_fleet

pytestmark = pytest.mark.slow

RIG = "kit"
TOML = f"""
[rig_defaults]
power_off_grace = 600
idle_limit = 600

[[rigs]]
id = "{RIG}"
spec = "sim:kit"
agent = true
"""
STEP = {"dt": 2.0, "samples": 600, "signal": "step:0:60@20", "methods": ["srm", "lsm"]}


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[Fleet]:
    made = make_fleet(tmp_path, TOML)
    try:
        made.start_lab(made.cert, made.key, grace=30.0)  # type: ignore[attr-defined]
        made.start_agent(RIG, "sim:kit", speedup=100.0)
        yield made
    finally:
        made.stop()


def _ended(client: httpx.Client, run_id: int) -> dict[str, Any] | None:
    client.post(f"/api/rigs/{RIG}/heartbeat")  # the controller is there: its turn goes on
    run: dict[str, Any] = client.get(f"/api/runs/{run_id}").json()
    return run if run["status"] != "running" else None


def test_a_hosted_kit_run_steps_heater_2_and_identifies_sensor_2(fleet: Fleet) -> None:
    with (
        contextlib.closing(fleet.client("tina")) as teacher,
        contextlib.closing(fleet.client("ana")) as ana,
    ):
        fleet.wait_online(teacher, RIG)
        assert ana.post(f"/api/rigs/{RIG}/control").json()["access"]["role"] == "controller"
        # A pair the kit lacks is refused by the lab, before anything reaches the host.
        refused = ana.post(f"/api/rigs/{RIG}/runs", json={**STEP, "input": "q3"})
        assert (refused.status_code, refused.json()["code"]) == (422, "pair_channel_unknown")
        answer = ana.post(f"/api/rigs/{RIG}/runs", json={**STEP, "input": "q2", "output": "t2"})
        assert answer.status_code == 201, answer.text
        run_id = answer.json()["id"]
        deadline = time.monotonic() + 180.0
        while (run := _ended(ana, run_id)) is None:
            assert time.monotonic() < deadline, "the hosted run did not end"
            time.sleep(0.5)
        assert (run["status"], run["endReason"]) == ("finished", "completed"), run
        assert (run["settings"]["input"], run["settings"]["output"]) == ("q2", "t2")

        samples = ana.get(f"/api/runs/{run_id}/export.json").json()["samples"]
        assert set(samples["u"]) == {0.0}  # heater 1 rested
        assert (samples["q2"][0], samples["q2"][-1]) == (0.0, 60.0)
        t2 = samples["t2"][-1] - samples["t2"][0]
        t1 = samples["y"][-1] - samples["y"][0]
        assert t2 > 15.0
        assert t2 > 2 * t1
        for method in ("srm", "lsm"):
            result = run["results"][method]
            latest = result["latest"]
            assert latest["valid"], (method, latest)
            # Heater 2 -> sensor 2: about 0.3 °C/% (half heater 1's 0.6), minutes; the
            # record's own gain. Fed heater 1 and sensor 1, K would be about 0.
            assert 0.2 < latest["K"] < 0.45, (method, latest)
            assert 60.0 < latest["tau"] < 400.0, (method, latest)
            assert latest["K"] == pytest.approx(t2 / 60.0, rel=0.25)
            # Judged on the pair's columns of the stored record: the model follows them.
            assert result["verdict"]["fit_record"] > 80.0, (method, result["verdict"])
