"""The student chooses the pair a run identifies (issue #22): heater 2 → sensor 2 on ``sim:kit``.

``POST /api/rigs/{rig}/runs`` with ``input: "q2"``, ``output: "t2"`` steps
heater 2 with the run's signal (heater 1 rests at 0), the methods identify
sensor 2's answer to it, and the run's settings (and so its export) say which
pair; a pair the rig lacks, or in the wrong roles, is refused with its code.
"""

from __future__ import annotations

import csv
import io

import pytest

from .conftest import LabFactory
from .test_kit_channels import RIG, kit, kit_lab
from .test_runs import api_client, person

STEP = {"dt": 2.0, "samples": 600, "signal": "step:0:60@20", "methods": ["srm", "lsm"]}


def test_a_q2_to_t2_run_steps_heater_2_and_identifies_sensor_2(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    person(lab, "ana")
    ana = api_client(lab, "ana")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    answer = ana.post(f"/api/rigs/{RIG}/runs", json={**STEP, "input": "q2", "output": "t2"})
    assert answer.status_code == 201, answer.text
    run_id = answer.json()["id"]
    lab.runs.wait(RIG, timeout=120)
    assert kit(lab).level("q2") == 0.0  # the run's end puts heater 2 off
    run = ana.get(f"/api/runs/{run_id}").json()
    assert (run["status"], run["endReason"]) == ("finished", "completed"), run
    assert (run["settings"]["input"], run["settings"]["output"]) == ("q2", "t2")
    # Heater 2 took the step, heater 1 rested; sensor 2 warmed more than sensor 1.
    text = ana.get(f"/api/runs/{run_id}/samples.csv").text
    rows = list(csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#")))
    assert {float(r["u"]) for r in rows} == {0.0}
    assert float(rows[0]["q2"]) == 0.0
    assert float(rows[-1]["q2"]) == 60.0
    t2 = float(rows[-1]["t2"]) - float(rows[0]["t2"])
    t1 = float(rows[-1]["y"]) - float(rows[0]["y"])
    assert t2 > 15.0
    assert t2 > 2 * t1
    for method in ("srm", "lsm"):
        latest = run["results"][method]["latest"]
        assert latest["valid"], (method, latest)
        # The kit's heater 2 -> sensor 2: about 0.3 °C/% (half heater 1's 0.6), minutes.
        assert 0.2 < latest["K"] < 0.45, (method, latest)
        assert 60.0 < latest["tau"] < 400.0, (method, latest)
        assert latest["K"] == pytest.approx(t2 / 60.0, rel=0.25)  # the record's own gain
    exported = ana.get(f"/api/runs/{run_id}/export.json").json()
    assert (exported["run"]["settings"]["input"], exported["run"]["settings"]["output"]) == (
        "q2",
        "t2",
    )


def test_a_standard_run_says_its_pair_is_u_and_y(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    person(lab, "ana")
    ana = api_client(lab, "ana")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    body = {"dt": 1.0, "samples": 5, "setpoint": 10.0, "methods": ["lsm"]}
    answer = ana.post(f"/api/rigs/{RIG}/runs", json=body)
    assert answer.status_code == 201, answer.text
    lab.runs.wait(RIG, timeout=60)
    settings = ana.get(f"/api/runs/{answer.json()['id']}").json()["settings"]
    assert (settings["input"], settings["output"]) == ("u", "y")


@pytest.mark.parametrize(
    ("pair", "code", "language", "sentence", "detail"),
    [
        (
            {"input": "q3"},
            "pair_channel_unknown",
            "pt-BR",
            "Esta bancada não tem canal com esse nome",
            "no channel 'q3'; its inputs: u, q2; its outputs: y, t2",
        ),
        (
            {"output": "t3"},
            "pair_channel_unknown",
            "es",
            "Este equipo no tiene un canal con ese nombre",
            "no channel 't3'",
        ),
        (
            {"input": "t2"},
            "pair_wrong_role",
            "en",
            "The pair's input must be one of the rig's heaters",
            "the pair's input 't2' is an output",
        ),
        (
            {"input": "q2", "output": "q2"},
            "pair_wrong_role",
            "pt-BR",
            "A entrada do par deve ser um dos aquecedores",
            "the pair's output 'q2' is an input",
        ),
    ],
)
def test_a_pair_the_rig_does_not_have_is_refused_with_its_code(
    make_lab: LabFactory,
    pair: dict[str, str],
    code: str,
    language: str,
    sentence: str,
    detail: str,
) -> None:
    lab = kit_lab(make_lab)
    person(lab, "ana")
    ana = api_client(lab, "ana")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    answer = ana.post(
        f"/api/rigs/{RIG}/runs",
        json={**STEP, **pair},
        headers={"Accept-Language": language},
    )
    assert (answer.status_code, answer.json()["code"]) == (422, code), answer.text
    assert answer.json()["message"].startswith(sentence)
    assert detail in answer.json()["detail"]
    assert lab.runs.running(RIG) is None


def test_a_closed_loop_run_keeps_the_standard_pair(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    person(lab, "ana")
    ana = api_client(lab, "ana")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    loop = {"setpoint": 40.0, "kp": 2.0, "ti": 100.0}
    body = {"dt": 1.0, "samples": 10, "control": loop, "input": "q2", "output": "t2"}
    answer = ana.post(f"/api/rigs/{RIG}/runs", json=body)
    assert (answer.status_code, answer.json()["code"]) == (422, "invalid_parameter"), answer.text
    assert "open loop" in answer.json()["detail"]
    assert lab.runs.running(RIG) is None
    assert ana.get("/api/runs").json() == []  # refused before anything was stored
