"""The kit's heater 2 and sensor 2 through the lab (issue #22, item 1), on its twin ``sim:kit``.

The controller sets heater 2 (``PUT /api/rigs/{rig}/channels/q2``) on the idle
rig or into its run, reads sensor 2 beside sensor 1, the run's record has
``t2`` and ``q2``, a watcher who joins the run late is replayed them, and every
end of a run or a turn hands heater 2 over at 0.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping

from fastapi.testclient import TestClient

from thermolab.lab.clock import ManualClock
from thermolab.lab.config import RigConfig
from thermolab.lab.http.app import create_app
from thermolab.lab.service import Lab
from thermolab.rigs import KitTwinRig, Rig, TwinRig, VirtualClock

from .conftest import LabFactory
from .test_handover import SPEEDUP
from .test_live import login
from .test_runs import StepClock, api_client, person, until

RIG = "twin"


def kit_lab(make_lab: LabFactory) -> Lab:
    from thermolab.lab.rigs.opener import device_opener

    return make_lab(opener=device_opener(), twin_speedup=SPEEDUP, spec="sim:kit")


def kit(lab: Lab) -> KitTwinRig:
    driver = lab.hub.driver(RIG)
    assert isinstance(driver, KitTwinRig)
    return driver


def heater_2(client: TestClient, level: float, **headers: str) -> tuple[int, dict[str, object]]:
    answer = client.put(f"/api/rigs/{RIG}/channels/q2", json={"level": level}, headers=headers)
    return answer.status_code, answer.json()


def shown_q2(client: TestClient) -> object:
    actuators = client.get(f"/api/rigs/{RIG}").json()["actuators"]
    return {a["name"]: a["level"] for a in actuators}["q2"]


def test_the_controller_sets_heater_2_and_reads_sensor_2(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    for name in ("ana", "ben"):
        person(lab, name)
    ana, ben = api_client(lab, "ana"), api_client(lab, "ben")
    assert heater_2(ana, 60.0)[0] == 403  # not at the controls yet
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    status, body = heater_2(ana, 60.0)
    assert status == 200, body
    assert (body["applied"], body["run"]) == (60.0, None)
    assert kit(lab).level("q2") == 60.0
    assert shown_q2(ana) == 60.0
    reading = ana.get(f"/api/rigs/{RIG}/reading").json()
    assert set(reading["channels"]) == {"t2", "q2"}
    assert reading["channels"]["q2"] == 60.0
    assert 10.0 < reading["channels"]["t2"] < 40.0
    assert heater_2(ben, 10.0)[0] == 403  # someone else's rig
    assert kit(lab).level("q2") == 60.0


def test_refusals_have_a_stable_code_and_a_sentence_in_the_readers_language(
    make_lab: LabFactory,
) -> None:
    lab = kit_lab(make_lab)
    person(lab, "ana")
    ana = api_client(lab, "ana")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    status, body = heater_2(ana, 150.0)
    assert (status, body["code"]) == (422, "invalid_parameter")
    answer = ana.put(
        f"/api/rigs/{RIG}/channels/fan", json={"level": 10}, headers={"Accept-Language": "pt-BR"}
    )
    assert (answer.status_code, answer.json()["code"]) == (422, "channel_not_on_rig")
    assert answer.json()["message"].startswith("Esta bancada não tem essa entrada")
    assert "no input 'fan'; its further inputs: q2" in answer.json()["detail"]
    answer = ana.put(
        "/api/rigs/other/channels/q2", json={"level": 10}, headers={"Accept-Language": "es"}
    )
    assert (answer.status_code, answer.json()["code"]) == (422, "channel_not_on_rig")
    assert answer.json()["message"].startswith("Este equipo no tiene esa entrada")


def test_a_release_hands_heater_2_over_at_0(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    for name in ("ana", "ben"):
        person(lab, name)
    ana, ben = api_client(lab, "ana"), api_client(lab, "ben")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    assert ben.post(f"/api/rigs/{RIG}/control").status_code == 200  # queued
    assert heater_2(ana, 90.0)[0] == 200
    assert ana.delete(f"/api/rigs/{RIG}/control").status_code == 200
    assert ben.get(f"/api/rigs/{RIG}").json()["access"]["role"] == "controller"
    assert kit(lab).level("q2") == 0.0
    assert shown_q2(ben) == 0.0


def test_a_q2_step_in_a_run_is_recorded_and_warms_t2(make_lab: LabFactory) -> None:
    lab = kit_lab(make_lab)
    person(lab, "ana")
    ana = api_client(lab, "ana")
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    body = {"dt": 1.0, "samples": 900, "setpoint": 0.0, "methods": ["lsm"]}
    answer = ana.post(f"/api/rigs/{RIG}/runs", json=body)
    assert answer.status_code == 201, answer.text
    run_id = answer.json()["id"]
    status, put = heater_2(ana, 80.0)  # an open-loop run takes it, as it takes the fan
    assert status == 200, put
    assert put["run"] == run_id
    until(lambda: kit(lab).level("q2") == 80.0)  # at the run's next sample
    lab.runs.wait(RIG, timeout=60)
    assert kit(lab).level("q2") == 0.0  # the run's end puts heater 2 off
    text = ana.get(f"/api/runs/{run_id}/samples.csv").text
    rows = list(csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#")))
    assert {"t2", "q2"} <= set(rows[0])
    q2 = [float(r["q2"]) for r in rows]
    t2 = [float(r["t2"]) for r in rows]
    on = next(k for k, level in enumerate(q2) if level == 80.0)
    assert set(q2[on:]) == {80.0}
    assert t2[-1] > t2[on] + 10.0  # heater 2 warms sensor 2
    channels = {c["name"]: c for c in ana.get(f"/api/runs/{run_id}").json()["channels"]}
    assert (channels["t2"]["unit"], channels["q2"]["unit"]) == ("degC", "%")
    paper = ana.get("/api/rigs/other").json()  # a one-heater twin has no further input
    assert [a["name"] for a in paper["actuators"]] == ["fan"]


def test_the_idle_monitoring_tells_listeners_sensor_2_and_heater_2(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = kit_lab(make_lab)
    person(lab, "ana")
    ana = api_client(lab, "ana")
    heard: list[Mapping[str, float | None] | None] = []

    class Listener:
        def access_changed(self, rig_id: str) -> None:
            pass

        def run_changed(self, rig_id: str, event: str, record: object) -> None:
            pass

        def run_event(self, rig_id: str, run_id: int, event: object) -> None:
            pass

        def reading(
            self,
            rig_id: str,
            u: object,
            y: float,
            at: object,
            channels: Mapping[str, float | None] | None = None,
        ) -> None:
            if rig_id == RIG:
                heard.append(channels)

    lab.add_listener(Listener())
    assert ana.post(f"/api/rigs/{RIG}/control").status_code == 200
    assert heater_2(ana, 30.0)[0] == 200
    clock.advance(1.0)
    lab.sweep()
    assert heard, "no idle reading announced"
    last = heard[-1]
    assert last is not None
    assert last["q2"] == 30.0
    assert isinstance(last["t2"], float)


def test_a_late_watcher_is_replayed_sensor_2_and_heater_2_from_the_store(
    make_lab: LabFactory,
) -> None:
    clock = StepClock()

    def opener(rig: RigConfig) -> Rig:
        if rig.id == RIG:
            return KitTwinRig(clock=clock, seed=1)
        return TwinRig("paper", clock=VirtualClock())

    lab = make_lab(opener=opener, spec="sim:kit")
    person(lab, "ana")
    client = TestClient(create_app(lab.config, lab=lab, sweep_interval=None))
    try:
        with client:
            ana = login(lab, "ana")
            assert client.post(f"/api/rigs/{RIG}/control", headers=ana).status_code == 200
            body = {"dt": 1.0, "samples": 100, "setpoint": 0.0, "methods": ["lsm"]}
            run_id = client.post(f"/api/rigs/{RIG}/runs", headers=ana, json=body).json()["id"]
            put = client.put(f"/api/rigs/{RIG}/channels/q2", headers=ana, json={"level": 40.0})
            assert put.status_code == 200, put.text
            clock.allow(19.0)
            until(lambda: lab.runs.record(run_id).samples_stored == 20)
            # since=0, as a page that opens the run half-way asks: its samples come from the store.
            with client.websocket_connect(f"/api/rigs/{RIG}/live?since=0", headers=ana) as ws:
                assert ws.receive_json()["type"] == "hello"
                stored = ws.receive_json()
            assert stored["type"] == "samples"
            items = stored["items"]
            assert [item["k"] for item in items] == list(range(20))
            assert all(set(item["channels"]) == {"t2", "q2"} for item in items)
            assert all(10.0 < item["channels"]["t2"] < 40.0 for item in items)
            assert items[-1]["channels"]["q2"] == 40.0  # the level set into the run
            # The other rig's one-channel run is replayed as before, with no channels.
            clock.allow(math.inf)
            lab.runs.wait(RIG, timeout=30)
            assert client.post("/api/rigs/other/control", headers=ana).status_code == 200
            other = {"dt": 1.0, "samples": 5, "methods": ["lsm"]}
            other_id = client.post("/api/rigs/other/runs", headers=ana, json=other).json()["id"]
            lab.runs.wait("other", timeout=30)
        page = lab.runs.stored_samples.sample_page(other_id, None, 5)
        assert len(page) == 5
        assert lab.runs.stored_samples.further_channels(other_id) == ()
    finally:
        clock.allow(math.inf)
