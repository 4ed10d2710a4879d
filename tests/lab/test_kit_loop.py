"""The closed loop on either heater of the kit's twin ``sim:kit``, the other a disturbance.

Issue #22: "the closed-loop panel chooses which heater it controls while the
other can be stepped as a disturbance". A closed-loop START names the pair
(``heater``/``sensor``, default ``u``/``y``); the PID drives heater 2 from
sensor 2, heater 1 is stepped by hand (``PUT .../input``) mid-run and recorded,
a hand setting of heater 2 is refused (409 ``channel_in_loop``), a pair the rig
does not have is refused (422 ``loop_pair_not_on_rig``), and the run's end puts
both heaters back at their declared default.
"""

from __future__ import annotations

import csv
import io
from typing import Any

from fastapi.testclient import TestClient

from thermolab.lab.service import Lab

from .conftest import LabFactory
from .test_kit_channels import RIG, heater_2, kit, kit_lab
from .test_runs import api_client, person, until

SETPOINT = 40.0
#: A PI for either heater of the kit (the runner's tests/runner/test_loop_pair.py).
GAINS = {"kp": 5.0, "ti": 150.0}
DT, SAMPLES = 2.0, 750  # 1500 s of the kit, 7.5 s at the lab's twin speed-up (200)
STEP_AT = 600.0  # s of the run: heater 1 stepped by hand


def samples(client: TestClient, run_id: int) -> dict[str, list[float]]:
    text = client.get(f"/api/runs/{run_id}/samples.csv").text
    rows = list(csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#")))
    return {name: [float(r[name]) for r in rows] for name in rows[0]}


def start(client: TestClient, control: dict[str, Any], **body: Any) -> Any:
    given = {"dt": DT, "samples": SAMPLES, "setpoint": 0.0, "methods": ["lsm"], **body}
    return client.post(f"/api/rigs/{RIG}/runs", json={**given, "control": control})


def at_the_controls(lab: Lab) -> TestClient:
    person(lab, "ana")
    ana = api_client(lab, "ana")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    return ana


def test_the_loop_drives_heater_2_from_sensor_2_while_heater_1_is_stepped(
    make_lab: LabFactory,
) -> None:
    lab = kit_lab(make_lab)
    ana = at_the_controls(lab)
    pairs = ana.get(f"/api/rigs/{RIG}/loop").json()["pairs"]
    assert [(p["heater"], p["sensor"]) for p in pairs] == [("u", "y"), ("q2", "t2")]
    assert (pairs[1]["inputRange"], pairs[1]["outputLimit"]) == ([0.0, 100.0], 90.0)
    control = {"setpoint": SETPOINT, **GAINS, "heater": "q2", "sensor": "t2"}
    answer = start(ana, control)
    assert answer.status_code == 201, answer.text
    run_id = answer.json()["id"]
    # Heater 2 is the PID's: a hand setting is refused, in the reader's language.
    status, refused = heater_2(ana, 10.0, **{"Accept-Language": "pt-BR"})
    assert (status, refused["code"]) == (409, "channel_in_loop")
    assert refused["message"].startswith("A malha fechada comanda este aquecedor")
    assert "q2 is driven by this run's closed loop" in refused["detail"]
    # Heater 1 is stepped by hand mid-run: a disturbance, the loop stays in AUTO.
    clock = kit(lab).clock
    t0 = clock.now()
    until(lambda: clock.now() - t0 > STEP_AT)
    stepped = ana.put(f"/api/rigs/{RIG}/input", json={"u": 60.0})
    assert stepped.status_code == 200, stepped.text
    assert stepped.json()["run"] == run_id
    loop = ana.get(f"/api/rigs/{RIG}/loop").json()["loop"]
    assert (loop["heater"], loop["sensor"], loop["mode"]) == ("q2", "t2", "auto")
    lab.runs.wait(RIG, timeout=60)
    # Every actuator back at its declared default.
    assert (kit(lab).applied_input, kit(lab).level("q2")) == (0.0, 0.0)
    s = samples(ana, run_id)
    assert len(s["t"]) == SAMPLES
    u, q2, t2, r = s["u"], s["q2"], s["t2"], s["r"]
    on = next(k for k, level in enumerate(u) if level == 60.0)
    assert 0.8 * STEP_AT / DT < on < 0.95 * SAMPLES  # recorded mid-run...
    assert set(u[:on]) == {0.0}  # ...heater 1 at its default until then
    assert set(u[on:]) == {60.0}
    assert set(s["auto"]) == {1.0}
    assert set(r) == {SETPOINT}
    assert max(q2) > 30.0  # the PID drives heater 2...
    assert abs(t2[on - 1] - SETPOINT) < 1.0  # ...sensor 2 at the set point before the step
    assert max(t2[on:]) > SETPOINT + 0.5  # heater 1 warms sensor 2 through the kit...
    assert abs(sum(t2[-20:]) / 20 - SETPOINT) < 0.6  # ...and the PID brings it back
    assert sum(q2[-20:]) / 20 < sum(q2[on - 20 : on]) / 20 - 5.0  # with less of heater 2
    assert t2[0] < SETPOINT - 10.0  # where the open loop (heater 2 at rest) would stay
    # The record says which pair was controlled.
    run = ana.get(f"/api/runs/{run_id}").json()
    assert (run["settings"]["control"]["heater"], run["settings"]["control"]["sensor"]) == (
        "q2",
        "t2",
    )
    assert (run["control"]["heater"], run["control"]["sensor"]) == ("q2", "t2")
    # The measured figures are sensor 2's step to the set point, not sensor 1's.
    measured = ana.get(f"/api/runs/{run_id}/tuning").json()["closedLoop"]["measured"]
    assert 15.0 < measured["step"] < 25.0  # from the kit at rest to the set point
    # Sensor 1 never gets near 40 °C (an IAE of most of step x duration); sensor 2 does.
    assert measured["iae"] < 0.3 * measured["step"] * SAMPLES * DT


def test_a_loop_on_heater_1_leaves_heater_2_to_the_hand(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    ana = at_the_controls(lab)
    answer = start(ana, {"setpoint": 35.0, **GAINS}, samples=100)  # the default pair, u/y
    assert answer.status_code == 201, answer.text
    run_id = answer.json()["id"]
    status, put = heater_2(ana, 70.0)  # the further-inputs path, as a disturbance
    assert status == 200, put
    assert put["run"] == run_id
    until(lambda: kit(lab).level("q2") == 70.0)
    lab.runs.wait(RIG, timeout=60)
    assert kit(lab).level("q2") == 0.0
    s = samples(ana, run_id)
    assert 70.0 in s["q2"]
    assert max(s["u"]) > 0.0  # the PID drives heater 1
    settings = ana.get(f"/api/runs/{run_id}").json()["settings"]["control"]
    assert (settings["heater"], settings["sensor"]) == ("u", "y")


def test_a_pair_the_rig_does_not_have_is_refused_with_its_code(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    ana = at_the_controls(lab)
    es = {"Accept-Language": "es"}
    for heater, sensor in (("q3", "t3"), ("q2", "y")):
        control = {"setpoint": SETPOINT, **GAINS, "heater": heater, "sensor": sensor}
        answer = ana.post(
            f"/api/rigs/{RIG}/runs",
            json={"dt": DT, "samples": 10, "setpoint": 0.0, "control": control},
            headers=es,
        )
        assert answer.status_code == 422, answer.text
        body = answer.json()
        assert body["code"] == "loop_pair_not_on_rig"
        assert body["message"].startswith("Este equipo no tiene ese par de calentador y sensor")
        assert f"{heater}/{sensor}" in body["detail"]
        assert "its pairs: u/y, q2/t2" in body["detail"]
    assert lab.running(RIG) is None
    # A one-heater rig (the paper's twin) has the run's own pair only.
    paper = ana.get("/api/rigs/other/loop").json()["pairs"]
    assert [(p["heater"], p["sensor"]) for p in paper] == [("u", "y")]
