"""The tuning table tunes a loop only with a model of its own pair (a kit's Q1/T1, Q2/T2).

A kit's run may identify heater 2 -> sensor 2 (``input: "q2"``); the closed
loop may control either pair. ``GET /api/runs/{id}/tuning?heater=&sensor=``
offers a run's model for the loop only if the run identified that loop's
heater and sensor, and says which pair a table's model is of; a Q2 -> T2
model asked for the Q1/T1 loop (or the reverse) is refused with its code.
"""

from __future__ import annotations

from fastapi.testclient import TestClient

from .conftest import LabFactory
from .test_kit_channels import RIG, kit_lab
from .test_runs import api_client, person

STEP = {"dt": 2.0, "samples": 600, "signal": "step:0:60@20", "methods": ["srm", "lsm"]}
LOOPS = {"q2/t2": {"heater": "q2", "sensor": "t2"}, "u/y": {"heater": "u", "sensor": "y"}}


def identify(client: TestClient, lab: object, pair: dict[str, str]) -> int:
    answer = client.post(f"/api/rigs/{RIG}/runs", json={**STEP, **pair})
    assert answer.status_code == 201, answer.text
    lab.runs.wait(RIG, timeout=120)  # type: ignore[attr-defined]
    run = client.get(f"/api/runs/{answer.json()['id']}").json()
    assert run["status"] == "finished", run
    return int(run["id"])


def test_each_loop_is_offered_only_its_own_pairs_model(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    person(lab, "ana")
    ana = api_client(lab, "ana")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    runs = {
        "q2/t2": identify(ana, lab, {"input": "q2", "output": "t2"}),
        "u/y": identify(ana, lab, {}),  # a run that names no pair identifies u -> y
    }
    for loop, params in LOOPS.items():
        for model, run_id in runs.items():
            answer = ana.get(
                f"/api/runs/{run_id}/tuning", params=params, headers={"Accept-Language": "pt-BR"}
            )
            if model == loop:
                assert answer.status_code == 200, answer.text
                table = answer.json()["table"]
                want = {"input": params["heater"], "output": params["sensor"]}
                assert table["pair"] == want
                assert table["rows"], table
            else:
                assert answer.status_code == 422, answer.text
                body = answer.json()
                assert body["code"] == "model_pair_mismatch", body
                assert body["message"].startswith("Este ensaio identificou outro par"), body
    # The heater alone names its loop (q2 goes with t2); without a loop the table says its pair.
    alone = ana.get(f"/api/runs/{runs['q2/t2']}/tuning", params={"heater": "q2"})
    assert alone.status_code == 200, alone.text
    plain = ana.get(f"/api/runs/{runs['u/y']}/tuning").json()["table"]
    assert plain["pair"] == {"input": "u", "output": "y"}
    # The Q2 -> T2 table steps from sensor 2's start, heater 2 at rest.
    q2 = ana.get(f"/api/runs/{runs['q2/t2']}/tuning", params=LOOPS["q2/t2"]).json()["table"]
    assert q2["u0"] == 0.0
    assert q2["setpoint"] > q2["y0"]
    # A loop the rig does not pair is refused as such.
    wrong = ana.get(f"/api/runs/{runs['u/y']}/tuning", params={"heater": "u", "sensor": "t2"})
    assert (wrong.status_code, wrong.json()["code"]) == (422, "loop_pair_not_on_rig")
