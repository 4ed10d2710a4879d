"""The twin speed-up, a teacher setting per rig (issue #10 item 3).

A twin the lab runs has a clock of its own whose rate the hub sets: at START
(the run keeps it), and on a save while no run is going. Hardware and a rig
host's twin do not have the setting. Rates and simulated time are asserted,
never wall-clock durations.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from thermolab.errors import (
    InvalidParameterError,
    SettingNotForRigError,
    SettingRangeError,
    SpeedupRefusedError,
)
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import LabConfig, RigConfig
from thermolab.lab.db import Database
from thermolab.lab.http.app import create_app
from thermolab.lab.runs import RunRequest
from thermolab.lab.runs.request import check_run_length
from thermolab.lab.service import Lab
from thermolab.rigs import RateClock, Rig, TwinRig

from .conftest import FAST_HASHER, PASSWORD, LabFactory
from .test_runs import StepClock, person, until

# On SQLite alone: the twin's clock rate (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only

#: A rig of each sort: a twin the lab runs, a kit, a twin on a rig host.
RIGS = (
    RigConfig("twin", "Twin", "sim"),
    RigConfig("kit", "Kit", "tclab"),
    RigConfig("host", "Host's twin", "sim", agent=True),
)


@pytest.fixture
def mixed_lab(tmp_path: Path, database_url: str, clock: ManualClock) -> Iterator[Lab]:
    config = LabConfig(data_dir=tmp_path, rigs=RIGS, database_url=database_url)
    lab = Lab(config, clock=clock, hasher=FAST_HASHER, database=Database(database_url))
    lab.start()
    yield lab
    lab.close()


def _gated_twin(source: StepClock) -> Callable[[RigConfig], Rig]:
    """Twins on rate clocks over ``source``, which passes only as far as the test allows."""

    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=RateClock(rig.twin_speedup, source=source))

    return opener


def test_a_saved_speedup_paces_the_next_run_and_a_run_going_keeps_its_own(
    make_lab: LabFactory,
) -> None:
    source = StepClock()
    try:
        lab = make_lab(opener=_gated_twin(source))
        tina, ana = person(lab, "tina", "admin"), person(lab, "ana")
        assert lab.hub.clock_rate("twin") == 1.0  # the file's first value
        # No run going: the twin takes the new pace at once.
        lab.settings.update("twin", tina, {"twin_speedup": 50.0}, 1)
        assert lab.hub.clock_rate("twin") == 50.0
        assert lab.hub.clock_rate("other") == 1.0  # only that rig

        lab.access.request_control("twin", ana)
        request = RunRequest(dt=1.0, samples=100, signal="step:0:4@1")
        first = lab.runs.start("twin", ana, request)
        # Saved while the run goes: in force for the next run, not on this run's clock.
        lab.settings.update("twin", tina, {"twin_speedup": 200.0}, 2)
        assert lab.config.rig("twin").twin_speedup == 200.0
        assert lab.hub.clock_rate("twin") == 50.0
        started_at = source.now()
        source.allow(math.inf)
        lab.runs.wait("twin", timeout=60)
        assert lab.runs.get(first.id, ana).status == "finished"
        # 99 sample periods of simulated time took 99 / 50 source seconds: the run's pace.
        assert source.now() - started_at == pytest.approx(99.0 / 50.0, rel=1e-6)
        until(lambda: lab.hub.clock_rate("twin") == 200.0, timeout=60)  # after the run

        before = source.now()  # the gate is open: the run goes on at once
        second = lab.runs.start("twin", ana, request)
        assert lab.hub.clock_rate("twin") == 200.0
        lab.runs.wait("twin", timeout=60)
        assert lab.runs.get(second.id, ana).status == "finished"
        assert source.now() - before == pytest.approx(99.0 / 200.0, rel=1e-6)
    finally:
        source.allow(math.inf)


def test_the_maximum_run_counts_the_rigs_own_speedup(make_lab: LabFactory) -> None:
    lab = make_lab(max_run_seconds=100.0)
    tina = person(lab, "tina", "admin")
    long_run = RunRequest(dt=1.0, samples=2000, signal="step:0:4@1")

    def length(rig: str) -> float:
        return check_run_length(long_run, rig, lab.config, lab.hub.published(rig).speedup)

    with pytest.raises(InvalidParameterError, match=r"lasts 2000 s, longer than .* \(100 s\)"):
        length("twin")
    lab.settings.update("twin", tina, {"twin_speedup": 50.0}, 1)
    assert lab.hub.published("twin").speedup == 50.0
    assert length("twin") == pytest.approx(40.0)
    # The other twin keeps its own speed-up (1): the same run lasts 2000 s there.
    assert length("other") == pytest.approx(2000.0)


def test_hardware_runs_in_real_time_and_a_hosts_twin_at_its_hosts_pace(mixed_lab: Lab) -> None:
    # A kit runs in real time; a host's twin at the pace its host said when it dialled
    # in, counted in real time before that.
    long_run = RunRequest(dt=1.0, samples=2000, signal="step:0:4@1")

    def length(rig: str) -> float:
        speedup = mixed_lab.hub.published(rig).speedup
        return check_run_length(long_run, rig, mixed_lab.config, speedup)

    assert mixed_lab.hub.published("host").speedup is None
    for rig in ("kit", "host"):
        assert length(rig) == pytest.approx(2000.0)
    mixed_lab.hub.host_said("host", 40.0)
    assert mixed_lab.hub.published("host").speedup == 40.0
    assert length("host") == pytest.approx(50.0)
    assert length("kit") == pytest.approx(2000.0)


def test_hardware_and_a_hosts_twin_have_no_speedup_setting(mixed_lab: Lab) -> None:
    tina = person(mixed_lab, "tina", "admin")
    app = create_app(mixed_lab.config, lab=mixed_lab, sweep_interval=None)
    with TestClient(app) as teacher:
        login = teacher.post("/api/session", json={"username": "tina", "password": PASSWORD})
        assert login.status_code == 200
        names = {
            rig: [s["name"] for s in teacher.get(f"/api/rigs/{rig}/settings").json()["settings"]]
            for rig in ("twin", "kit", "host")
        }
        assert "twin_speedup" in names["twin"]
        assert "twin_speedup" not in names["kit"]
        assert "twin_speedup" not in names["host"]
        for rig in ("kit", "host"):
            refused = teacher.put(
                f"/api/rigs/{rig}/settings",
                json={"version": 1, "values": {"twin_speedup": 10, "control_time_limit": 60}},
            )
            assert refused.status_code == 422, refused.text
            body = refused.json()
            assert body["code"] == "setting_not_for_rig"
            assert body["errors"][0]["loc"] == ["body", "values", "twin_speedup"]
            assert f"rig {rig!r} has no setting twin_speedup" in body["detail"]
            assert body["message"] == "This rig does not have that setting."
            # Nothing saved.
            assert teacher.get(f"/api/rigs/{rig}/settings").json()["version"] == 1
        # The listing publishes each rig's speed-up (a host's twin: unknown to the lab).
        speedups = {rig["id"]: rig["speedup"] for rig in teacher.get("/api/rigs").json()}
        assert speedups == {"twin": 1.0, "kit": 1.0, "host": None}
        saved = teacher.put(
            "/api/rigs/twin/settings", json={"version": 1, "values": {"twin_speedup": 25}}
        )
        assert saved.status_code == 200, saved.text
        assert teacher.get("/api/rigs/twin").json()["speedup"] == 25.0
    with pytest.raises(SettingNotForRigError):
        mixed_lab.settings.update("kit", tina, {"twin_speedup": 2.0}, 1)


@pytest.mark.parametrize("value", [0.5, 0, -3, 1000.5, 1e9])
def test_a_speedup_out_of_range_is_refused_with_the_range(lab: Lab, value: float) -> None:
    lab.users.add("tina", PASSWORD, "teacher", admin=True)
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with TestClient(app) as teacher:
        teacher.post("/api/session", json={"username": "tina", "password": PASSWORD})
        refused = teacher.put(
            "/api/rigs/twin/settings", json={"version": 1, "values": {"twin_speedup": value}}
        )
        assert refused.status_code == 422, refused.text
        assert refused.json()["code"] == "setting_out_of_range"
        assert "allowed: 1 to 1000" in refused.json()["detail"]
    assert lab.config.rig("twin").twin_speedup == 1.0


def test_a_technicians_cap_bounds_the_speedup(make_lab: LabFactory) -> None:
    lab = make_lab(caps=(("twin_speedup", 100.0),))
    tina = person(lab, "tina", "admin")
    assert lab.settings.get("twin", tina).ranges["twin_speedup"] == (1.0, 100.0)
    with pytest.raises(SettingRangeError, match="allowed: 1 to 100"):
        lab.settings.update("twin", tina, {"twin_speedup": 150.0}, 1)


def test_serve_speedup_is_saved_as_every_lab_twins_speedup(
    tmp_path: Path, database_url: str, clock: ManualClock
) -> None:
    config = LabConfig(data_dir=tmp_path, rigs=RIGS, database_url=database_url).with_overrides(
        speedup=30.0
    )
    labs = []
    try:
        for _ in range(2):  # a restart with the same --speedup saves nothing more
            lab = Lab(config, clock=clock, hasher=FAST_HASHER, database=Database(database_url))
            labs.append(lab)
            lab.start()
            tina = person(lab, f"tina{len(labs)}", "admin")
            twin = lab.settings.get("twin", tina)
            assert (twin.values["twin_speedup"], twin.version, twin.updated_by) == (30.0, 2, None)
            assert lab.config.rig("twin").speedup == 30.0
            assert "twin_speedup" not in lab.settings.get("kit", tina).values
            assert lab.settings.get("kit", tina).version == 1
    finally:
        for lab in labs:
            lab.close()


def test_a_controller_paces_the_twin_for_their_turn_within_what_it_allows(
    make_lab: LabFactory,
) -> None:
    source = StepClock()
    try:
        lab = make_lab(opener=_gated_twin(source), twin_speedup=50.0)
        ana, _ = person(lab, "ana"), person(lab, "ben")
        app = create_app(lab.config, lab=lab, sweep_interval=None)
        with TestClient(app) as client, TestClient(app) as other:
            for who, name in ((client, "ana"), (other, "ben")):
                login = who.post("/api/session", json={"username": name, "password": PASSWORD})
                assert login.status_code == 200

            def pace(who: TestClient, speedup: float) -> Any:
                return who.put("/api/rigs/twin/control/speedup", json={"speedup": speedup})

            assert pace(client, 10.0).status_code == 403  # only the controller's turn
            assert client.post("/api/rigs/twin/control").status_code == 200
            answer = pace(client, 10.0)
            assert answer.status_code == 200, answer.text
            assert answer.json()["speedup"] == 10.0
            assert lab.hub.clock_rate("twin") == 10.0
            assert other.get("/api/rigs/twin").json()["speedup"] == 10.0  # what the twin does
            for refused in (80.0, 0.5):
                answer = pace(client, refused)
                assert answer.status_code == 422
                assert answer.json()["code"] == "speedup_refused"
                assert (
                    "rig 'twin' (a twin) allows speed-ups from 1x to 50x"
                    in (answer.json()["detail"])
                )
            assert pace(client, 0.0).status_code == 422  # not a speed-up at all
            assert lab.hub.clock_rate("twin") == 10.0
            # A run keeps the pace it started with.
            lab.runs.start("twin", ana, RunRequest(dt=1.0, samples=100, signal="step:0:4@1"))
            answer = pace(client, 5.0)
            assert answer.status_code == 409
            assert "keeps the pace it started with" in answer.json()["detail"]
            # The turn's end (the run's with it) gives the twin the teacher's pace back.
            assert client.delete("/api/rigs/twin/control").status_code == 200
            source.allow(math.inf)
            lab.runs.wait("twin", timeout=60)
            until(lambda: lab.hub.clock_rate("twin") == 50.0)
            assert other.get("/api/rigs/twin").json()["speedup"] == 50.0
    finally:
        source.allow(math.inf)


def test_hardware_and_a_hosts_twin_refuse_a_turns_speedup_naming_why(mixed_lab: Lab) -> None:
    for rig, spec in (("kit", "tclab"), ("host", "sim")):
        with pytest.raises(SpeedupRefusedError, match=rf"rig '{rig}' \({spec}\) runs at its own"):
            mixed_lab.hub.pace_turn(rig, 2.0, controller_session=1)
