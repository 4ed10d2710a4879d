"""Closed-loop runs through the API: PID on the twin and the emulated TCLab kit.

START with ``control``, switch manual/auto, change the set point, the gains and the
disturbance fan while the run goes; the tuning table from an identified model. The
rigs are a twin on a :class:`StepClock` (a run takes only the samples a test allows)
and the firmware emulator behind the real TCLab driver.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from thermolab.control import LoopWord, tune
from thermolab.lab.config import RigConfig
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig, VirtualClock
from thermolab.rigs.tclab import TCLabRig
from thermolab.rigs.tclab_emulator import TCLabEmulator

from .conftest import LabFactory
from .test_runs import StepClock, api_client, person, until

# On SQLite alone: closed-loop commands and their answers (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only

KIT = (0.6, 140.0, 15.9)  # the kit twin's FOPDT figures
PAPER = (0.140090, 250.126233, 0.5)


@pytest.fixture
def step_clock() -> Iterator[StepClock]:
    clock = StepClock()
    yield clock
    clock.allow(math.inf)


def closed_loop_lab(make_lab: LabFactory, clock: Any, **overrides: Any) -> Lab:
    def opener(rig: RigConfig) -> Rig:
        preset = "paper" if rig.id == "twin" else "tclab"
        return TwinRig(preset, clock=clock, realism=False, **overrides)

    return make_lab(opener=opener)


def controller(lab: Lab, rig: str = "twin", name: str = "ana") -> TestClient:
    person(lab, name)
    client = api_client(lab, name)
    assert client.post(f"/api/rigs/{rig}/control").status_code == 200
    return client


def start(
    client: TestClient, rig: str, samples: int, control: dict[str, Any] | None, **run: Any
) -> int:
    body = {"dt": 1.0, "samples": samples, "methods": ["lsm"], "control": control, **run}
    response = client.post(f"/api/rigs/{rig}/runs", json=body)
    assert response.status_code == 201, response.text
    run_id: int = response.json()["id"]
    return run_id


def channels(client: TestClient, run_id: int) -> dict[str, np.ndarray]:
    samples = client.get(f"/api/runs/{run_id}/export.json").json()["samples"]
    return {
        name: np.array([math.nan if v is None else v for v in values], dtype=float)
        for name, values in samples.items()
    }


def taken(lab: Lab, client: TestClient, run_id: int, k: int) -> None:
    """Wait until the run has taken and stored ``k`` samples."""
    until(lambda: client.get(f"/api/runs/{run_id}").json()["samplesStored"] >= k)


def test_the_control_parameters_are_published_from_their_declaration(
    make_lab: LabFactory,
) -> None:
    lab = closed_loop_lab(make_lab, VirtualClock())
    client = controller(lab)
    body = client.get("/api/control").json()
    kp = next(p for p in body["parameters"] if p["name"] == "kp")
    assert (kp["minimum"], kp["maximum"], kp["magnitude"]) == (1e-6, 1e4, True)
    assert [r["name"] for r in body["rules"]] == ["imc", "simc", "zn", "cc"]
    schema = client.get("/openapi.json").json()["components"]["schemas"]
    assert schema["GainsIn"]["properties"]["ti"]["maximum"] == 1e6
    loop = client.get("/api/rigs/twin/loop").json()
    assert loop["fan"]["unit"] == "%"
    assert loop["closedLoop"] is True
    assert loop["outputLimit"] == 5.0
    assert loop["loop"] is None


def test_anti_windup_at_saturation_on_the_twin(make_lab: LabFactory) -> None:
    # Set point 1.3 V on the paper twin (at most 1.4 V at 10 V): the heater saturates for
    # most of the rise. Without anti-windup the integral would grow all that time and
    # overshoot far; with back-calculation the output settles without a large overshoot.
    lab = closed_loop_lab(make_lab, VirtualClock())
    client = controller(lab)
    run_id = start(client, "twin", 3000, {"setpoint": 1.3, "kp": 200.0, "ti": 50.0})
    lab.runs.wait("twin", timeout=60)
    run = client.get(f"/api/runs/{run_id}").json()
    assert run["status"] == "finished"
    assert run["control"]["mode"] == "auto"
    data = channels(client, run_id)
    saturated = np.flatnonzero(data["u"] == 10.0)
    assert saturated.size > 500  # a long stretch at the limit
    assert data["y"].max() < 1.3 * 1.02  # the integral did not wind up
    assert abs(data["y"][-1] - 1.3) < 1e-3
    np.testing.assert_allclose(data["r"], 1.3)
    np.testing.assert_allclose(data["e"], data["r"] - data["y"], atol=1e-12)


def test_bumpless_transfer_and_live_commands_through_the_api(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = closed_loop_lab(make_lab, step_clock)
    client = controller(lab)
    gains = tune(PAPER, "simc", tau_c=100.0).gains
    run_id = start(
        client, "twin", 2000,
        {"mode": "manual", "setpoint": 0.7, "kp": gains.Kp, "ti": gains.Ti},
        setpoint=5.0,
    )  # fmt: skip
    step_clock.allow(399.0)
    taken(lab, client, run_id, 400)
    state = client.get("/api/rigs/twin/loop").json()["loop"]
    assert state["mode"] == "manual"
    # MANUAL -> AUTO at the set point in force (0.7 V, above where the box is): no bump,
    # the integral takes the box there.
    answer = client.put("/api/rigs/twin/runs/current/mode", json={"mode": "auto"})
    assert answer.status_code == 200, answer.text
    step_clock.allow(599.0)
    taken(lab, client, run_id, 600)
    answer = client.put("/api/rigs/twin/runs/current/setpoint", json={"setpoint": 0.8})
    assert answer.status_code == 200, answer.text
    step_clock.allow(699.0)
    taken(lab, client, run_id, 700)
    assert (
        client.put(
            "/api/rigs/twin/runs/current/gains", json={"kp": gains.Kp * 2, "ti": gains.Ti}
        ).status_code
        == 200
    )
    step_clock.allow(899.0)
    taken(lab, client, run_id, 900)
    assert client.put("/api/rigs/twin/runs/current/fan", json={"percent": 80}).status_code == 200
    step_clock.allow(math.inf)
    lab.runs.wait("twin", timeout=60)
    data = channels(client, run_id)
    auto = np.flatnonzero(data["auto"] == 1.0)
    switch = int(auto[0])
    assert 399 <= switch <= 402
    assert np.all(data["u"][:switch] == 5.0)
    # Bumpless: the first AUTO samples continue from the manual input.
    assert np.max(np.abs(data["u"][switch : switch + 5] - 5.0)) < 0.05
    gains_change = np.abs(np.diff(data["u"][695:710]))
    assert gains_change.max() < 0.05  # the gain change is bumpless too
    fan_on = int(np.flatnonzero(data["fan"] == 80.0)[0])
    assert 899 <= fan_on <= 902
    assert data["u"][-1] > data["u"][fan_on - 1] + 0.5  # the PID heats against the fan
    assert abs(data["y"][-1] - 0.8) < 0.01
    assert set(data["r"][:600]) == {0.7}
    assert data["r"][-1] == 0.8
    run = client.get(f"/api/runs/{run_id}").json()
    assert run["control"]["switches"] == 1
    assert run["settings"]["control"]["mode"] == "manual"


def test_the_interlock_wins_over_the_controller(make_lab: LabFactory) -> None:
    # A set point below the rig's limit but gains that overshoot past it: the rig's
    # output limit faults the run and the actuator goes safe, whatever the PID demands.
    clock = VirtualClock()
    lab = closed_loop_lab(make_lab, clock, output_limit=60.0)
    client = controller(lab, "other")
    # Ziegler-Nichols-like aggression on the kit's dead time: it overshoots past 60 degC.
    run_id = start(client, "other", 3000, {"setpoint": 57.0, "kp": 30.0, "ti": 10.0})
    lab.runs.wait("other", timeout=60)
    run = client.get(f"/api/runs/{run_id}").json()
    assert run["status"] == "failed"
    assert "limit" in run["endReason"]
    driver = lab.hub.driver("other")
    assert isinstance(driver, TwinRig)
    assert driver.applied_input == 0.0  # the safe state, whatever the PID demanded
    data = channels(client, run_id)
    assert data["y"].max() <= 60.0
    assert data["auto"][-1] == 1.0  # the PID was driving when the limit cut it
    assert data["u"].max() == 100.0


@pytest.fixture
def kit_lab(make_lab: LabFactory) -> Iterator[Lab]:
    clock = VirtualClock()
    with TCLabEmulator(clock=clock, seed=0, realism=False) as emulator:

        def opener(rig: RigConfig) -> Rig:
            if rig.id == "other":
                return TCLabRig(
                    emulator.port, clock=clock, reset_wait=0.0, timeout=5.0, watchdog=None
                )
            return TwinRig("paper", clock=clock, realism=False, output_unit="")

        yield make_lab(opener=opener)


def test_pid_on_the_emulated_kit_and_bad_input_codes(kit_lab: Lab) -> None:
    lab = kit_lab
    client = controller(lab, "other")
    gains = tune(KIT, "simc").gains
    url = "/api/rigs/other/runs/current"

    def refused(body: dict[str, Any], code: str) -> None:
        answer = client.post(
            "/api/rigs/other/runs",
            json={"dt": 1.0, "samples": 50, "methods": ["lsm"], "control": body},
        )
        assert answer.status_code == 422, answer.text
        assert answer.json()["code"] == code, answer.text
        assert answer.json()["detail"]

    good = {"setpoint": 40.0, "kp": gains.Kp, "ti": gains.Ti}
    refused({**good, "kp": 1e9}, "gain_out_of_range")
    refused({**good, "ti": 0.0}, "gain_out_of_range")
    refused({**good, "td": -1.0}, "gain_out_of_range")
    refused({**good, "setpoint": 95.0}, "setpoint_out_of_range")
    refused({**good, "every": 10}, "invalid_parameter")  # adaptive settings need adaptive
    answer = client.put(f"{url}/mode", json={"mode": "auto"})
    assert (answer.status_code, answer.json()["code"]) == (409, "no_run")
    # Someone who does not control the rig hears 403 first, run or not.
    person(lab, "bea")
    watcher = api_client(lab, "bea")
    answer = watcher.put(f"{url}/mode", json={"mode": "auto"})
    assert (answer.status_code, answer.json()["code"]) == (403, "access_denied")
    assert lab.runs.running("other") is None  # nothing was started by the refusals
    run_id = start(client, "other", 600, {**good, "model": list(KIT)})
    # inf is not JSON (Python's json sends Infinity, which the server reads as inf).
    answer = client.put(
        f"{url}/gains", content='{"kp": Infinity, "ti": 100.0}',
        headers={"content-type": "application/json"},
    )  # fmt: skip
    assert (answer.status_code, answer.json()["code"]) == (422, "gain_out_of_range")
    answer = client.put(f"{url}/gains", json={"kp": 1e300, "ti": 100.0})
    assert (answer.status_code, answer.json()["code"]) == (422, "gain_out_of_range")
    answer = client.put(f"{url}/fan", json={"percent": 50})
    assert answer.status_code == 422
    assert "no disturbance fan" in answer.json()["detail"]
    # A watcher may not command the run (going, or ended already on the fast clock).
    answer = watcher.put(f"{url}/setpoint", json={"setpoint": 30.0})
    assert (answer.status_code, answer.json()["code"]) == (403, "access_denied")
    lab.runs.wait("other", timeout=60)
    data = channels(client, run_id)
    assert abs(data["y"][-1] - 40.0) < 1.0
    assert np.all((data["u"] >= 0.0) & (data["u"] <= 100.0))
    assert "fan" not in data
    table = client.get(f"/api/runs/{run_id}/tuning").json()
    assert table["closedLoop"]["measured"]["overshoot"] is not None
    assert table["closedLoop"]["predicted"]["overshoot"] is not None
    # Each note by code beside the English ``note``: the same sentences.
    notes = table["closedLoop"]["notes"]
    said = "; ".join(LoopWord.of(n["code"], **n["params"]).text for n in notes)
    assert said == (table["closedLoop"]["note"] or "")
    # A rig without an output unit cannot be controlled.
    client.delete("/api/rigs/other/control")
    twin = controller(lab, "twin", "cai")
    answer = twin.post(
        "/api/rigs/twin/runs",
        json={"dt": 1.0, "samples": 10, "control": {"setpoint": 1.0, "kp": 1.0, "ti": 10.0}},
    )
    assert (answer.status_code, answer.json()["code"]) == (422, "no_output_unit")
    # An open-loop run takes no control command.
    start_open = twin.post("/api/rigs/twin/runs", json={"dt": 1.0, "samples": 5})
    assert start_open.status_code == 201
    answer = twin.put("/api/rigs/twin/runs/current/setpoint", json={"setpoint": 1.0})
    assert answer.status_code in (409,)
    assert answer.json()["code"] in ("not_closed_loop", "no_run")


def test_the_tuning_table_from_an_identified_model(make_lab: LabFactory) -> None:
    lab = closed_loop_lab(make_lab, VirtualClock())
    client = controller(lab, "other")
    response = client.post(
        "/api/rigs/other/runs",
        json={"dt": 1.0, "samples": 1200, "signal": "step:0:50@0", "methods": ["lsm"]},
    )
    assert response.status_code == 201, response.text
    lab.runs.wait("other", timeout=60)
    run_id = response.json()["id"]
    body = client.get(f"/api/runs/{run_id}/tuning", params={"setpoint": 50.0}).json()
    table = body["table"]
    assert table["method"] == "lsm"
    model = table["model"]
    assert model["K"] == pytest.approx(0.6, rel=0.05)
    assert model["theta"] > 5.0
    rows = {(r["rule"], r["form"]): r for r in table["rows"]}
    assert set(rows) == {
        ("imc", "pid"), ("imc", "pi"), ("simc", "pi"), ("zn", "pid"), ("zn", "pi"),
        ("cc", "pid"), ("cc", "pi"),
    }  # fmt: skip
    simc = rows[("simc", "pi")]
    expected = tune((model["K"], model["tau"], model["theta"]), "simc").gains
    assert simc["Kp"] == pytest.approx(expected.Kp, rel=1e-12)
    assert simc["predicted"]["settling_time"] > 0
    assert simc["response"]["y"][-1] == pytest.approx(50.0, abs=0.5)
    # tauC's published range is in the schema: refused before the route, one problem named.
    for tiny in (-1, 0, 5e-324, 1e-3):  # 5e-324 made the gains overflow: a 500 before
        answer = client.get(f"/api/runs/{run_id}/tuning", params={"tauC": tiny})
        assert (answer.status_code, answer.json()["code"]) == (422, "invalid_request")
        assert answer.json()["errors"][0]["loc"] == ["query", "tauC"]


def test_the_tuning_table_steps_from_rest_by_the_rigs_own_ranges(make_lab: LabFactory) -> None:
    """Issue #24: on the ±10 V box at rest at 0 V the middle of the range is no step."""
    lab = closed_loop_lab(make_lab, VirtualClock())
    box = controller(lab, "twin")
    # The quick start's first lesson: panel 3, WLSM on the Automatic square wave.
    run_id = start(box, "twin", 2000, None, signal="square:0:4:0.1", methods=["wlsm"])
    lab.runs.wait("twin", timeout=60)
    body = box.get(f"/api/runs/{run_id}/tuning").json()
    table = body["table"]
    assert table["method"] == "wlsm"
    assert table["model"]["K"] == pytest.approx(PAPER[0], rel=1e-3)
    # 0 V to 5 V of input (half the way to the range's end): 0.7 V of output, below 5 V.
    assert (table["y0"], table["u0"], table["setpoint"]) == (0.0, 0.0, 0.7)
    rows = {(r["rule"], r["form"]): r for r in table["rows"]}
    for rule in (("imc", "pid"), ("imc", "pi"), ("simc", "pi")):
        assert rows[rule]["predicted"]["settling_time"] > 0
        assert rows[rule]["response"]["y"][-1] == pytest.approx(0.7, abs=0.01)
    # Ziegler-Nichols and Cohen-Coon need a dead time, which WLSM's model has not: said why.
    assert "dead time" in rows[("zn", "pid")]["error"]
    # ... and by code, for a page to say it in its reader's language (issue #24).
    assert rows[("zn", "pid")]["why"] == {"code": "needs_dead_time", "params": {"rule": "zn"}}
    # The student's own set point; none at the start nor at the output limit.
    chosen = box.get(f"/api/runs/{run_id}/tuning", params={"setpoint": -0.5}).json()["table"]
    assert chosen["setpoint"] == -0.5
    assert chosen["rows"][0]["response"]["y"][-1] == pytest.approx(-0.5, abs=0.01)
    for setpoint, code in ((0.0, "setpoint_no_step"), (5.0, "setpoint_out_of_range")):
        answer = box.get(f"/api/runs/{run_id}/tuning", params={"setpoint": setpoint})
        assert (answer.status_code, answer.json()["code"]) == (422, code)
    # The kit twin: 0 % to 50 % of heater from the run's first output, about 30 degC up.
    kit = controller(lab, "other", "bea")
    run_id = start(kit, "other", 600, None, signal="step:0:50@0", methods=["lsm"])
    lab.runs.wait("other", timeout=60)
    table = kit.get(f"/api/runs/{run_id}/tuning").json()["table"]
    step = table["setpoint"] - table["y0"]
    assert step == pytest.approx(0.5 * 100 * table["model"]["K"], abs=0.6)
    assert table["setpoint"] == round(table["setpoint"])
