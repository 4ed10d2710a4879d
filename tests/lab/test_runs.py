"""Runs: START, set point changes, END, storage at least once a second, export, ownership.

The rigs are digital twins on a virtual clock (a run of 2000 samples takes a
fraction of a second) or on a :class:`StepClock` that lets a run take only the
samples a test allows, so that a run can be caught while it is going.
"""

from __future__ import annotations

import csv
import io
import math
import threading
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from thermolab.ident import least_squares
from thermolab.lab.app import create_app
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import RigConfig
from thermolab.lab.models import Command, Sample
from thermolab.lab.runs import RunRequest
from thermolab.lab.service import Lab
from thermolab.lab.users import Principal
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory


class StepClock:
    """A rig clock whose time only passes as far as the test allows."""

    def __init__(self) -> None:
        self._t = 0.0
        self._allowed = 0.0
        self._changed = threading.Condition()

    def now(self) -> float:
        return self._t

    def sleep_until(self, t: float) -> None:
        with self._changed:
            while t > self._allowed:
                self._changed.wait()
            self._t = max(self._t, t)

    def allow(self, t: float) -> None:
        with self._changed:
            self._allowed = max(self._allowed, t)
            self._changed.notify_all()


def until(condition: Callable[[], bool], timeout: float = 10.0) -> None:
    """Wait (in real time, briefly) for something another thread does."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.005)


def person(lab: Lab, name: str, role: str = "student") -> Principal:
    info = lab.users.add(name, PASSWORD, role)
    return Principal(info.id, info.username, info.role)


@pytest.fixture
def step_clock() -> Iterator[StepClock]:
    clock = StepClock()
    yield clock
    clock.allow(math.inf)  # never leave a run blocked behind a test


def twin_lab(make_lab: LabFactory, clock: object | None = None) -> Lab:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper" if rig.id == "twin" else "tclab", clock=clock or VirtualClock())

    return make_lab(opener=opener)


def stored_samples(lab: Lab, run_id: int) -> int:
    with lab.db.read() as session:
        return session.scalar(select(func.count()).where(Sample.run_id == run_id)) or 0


def test_a_run_is_sampled_identified_stored_and_exported(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = twin_lab(make_lab)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with TestClient(app) as client:
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        response = client.post(
            "/api/rigs/twin/runs",
            json={
                "dt": 1.0,
                "samples": 2000,
                "signal": "step:0:10@10",
                "methods": ["srm", "lsm", "malsm", "wlsm"],
                "window": 100,
                "gamma": 0.96,
            },
        )
        assert response.status_code == 201, response.text
        run_id = response.json()["id"]
        lab.runs.wait("twin", timeout=60)
        run = client.get(f"/api/runs/{run_id}").json()
        assert (run["status"], run["samplesStored"], run["endReason"]) == (
            "finished",
            2000,
            "completed",
        )
        assert run["settings"]["signal"] == "step:0:10@10"
        lsm = run["results"]["lsm"]["latest"]
        np.testing.assert_allclose([lsm["K"], lsm["tau"]], [0.140090, 250.126233], rtol=1e-6)
        srm = run["results"]["srm"]["latest"]
        np.testing.assert_allclose(srm["tau"], 250.126233, rtol=1e-5)

        # The CSV feeds straight back into the identification methods.
        text = client.get(f"/api/runs/{run_id}/samples.csv").text
        rows = list(csv.DictReader(io.StringIO(text)))
        assert list(rows[0]) == ["t", "u", "y", "k"]
        assert len(rows) == 2000
        u = np.array([float(r["u"]) for r in rows])
        y = np.array([float(r["y"]) for r in rows])
        again = least_squares(u, y, 1.0)
        np.testing.assert_allclose([again.K, again.tau], [0.140090, 250.126233], rtol=1e-6)

        exported = client.get(f"/api/runs/{run_id}/export.json").json()
        assert exported["run"]["id"] == run_id
        assert len(exported["samples"]["y"]) == 2000
        assert exported["samples"]["y"] == [float(r["y"]) for r in rows]
        wlsm = exported["methods"]["wlsm"]
        assert wlsm["params"]["gamma"] == 0.96
        assert len(wlsm["result"]["trajectory"]["K"]) == wlsm["result"]["estimates"] > 1000
        # After the run the rig is the controller's again, from the safe input.
        rig = client.get("/api/rigs/twin").json()
        assert (rig["state"], rig["access"]["role"]) == ("in_use", "controller")
        assert client.put("/api/rigs/twin/input", json={"u": 1.0}).json()["applied"] == 1.0


def test_only_the_controller_starts_a_run_and_one_at_a_time(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = twin_lab(make_lab, step_clock)
    ana, ben = person(lab, "ana"), person(lab, "ben")
    tina = person(lab, "tina", "teacher")
    request = lab_request(samples=100)
    with pytest.raises(Exception, match="only the controller of rig 'twin' may start a run"):
        lab.runs.start("twin", ana, request)
    lab.access.request_control("twin", ana)
    lab.access.request_control("twin", ben)
    with pytest.raises(Exception, match="another user controls it"):
        lab.runs.start("twin", ben, request)
    run = lab.runs.start("twin", ana, request)
    assert run.status == "running"
    with pytest.raises(Exception, match="already going on rig 'twin'"):
        lab.runs.start("twin", ana, request)
    with pytest.raises(Exception, match="only the controller of rig 'twin' may END"):
        lab.runs.stop("twin", ben)
    step_clock.allow(9.0)
    until(lambda: lab.runs.get(run.id, ana).samples_taken == 10)
    lab.runs.stop("twin", tina)  # a teacher may END anyone's run
    step_clock.allow(math.inf)
    lab.runs.wait("twin", timeout=30)
    done = lab.runs.get(run.id, ana)
    assert (done.status, done.end_reason) == ("stopped", "ended by tina")
    assert 10 <= done.samples_stored == stored_samples(lab, run.id) < 100


def test_samples_reach_the_database_while_the_run_goes(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = twin_lab(make_lab, step_clock)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, lab_request(samples=1000))
    step_clock.allow(49.0)
    # Written at least once a second (the writer flushes every 0.5 s) while still running.
    started = time.monotonic()
    until(lambda: stored_samples(lab, run.id) == 50, timeout=5)
    assert time.monotonic() - started < 2.0
    assert lab.runs.get(run.id, ana).status == "running"
    step_clock.allow(math.inf)
    lab.runs.wait("twin", timeout=30)
    assert stored_samples(lab, run.id) == 1000


def test_set_point_changes_go_to_the_run_and_are_recorded(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = twin_lab(make_lab, step_clock)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, lab_request(samples=40, signal=None, setpoint=2.0))
    step_clock.allow(9.0)
    until(lambda: lab.runs.get(run.id, ana).samples_taken == 10)
    result = lab.apply_input("twin", ana, 7.5)
    assert (result.applied, result.run_id) == (7.5, run.id)
    step_clock.allow(math.inf)
    lab.runs.wait("twin", timeout=30)
    us = [u for _, _, u, _ in lab.runs.samples(run.id, ana)]
    assert us[:10] == [2.0] * 10
    assert us[-1] == 7.5
    with lab.db.read() as session:
        kinds = [
            (c.kind, c.value, c.run_id)
            for c in session.scalars(select(Command).order_by(Command.id))
        ]
    assert kinds == [("run_start", None, run.id), ("input", 7.5, run.id)]


def test_a_run_ends_with_the_turn_it_belongs_to(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = twin_lab(make_lab, step_clock)
    ana, ben = person(lab, "ana"), person(lab, "ben")
    tina = person(lab, "tina", "teacher")
    lab.access.request_control("twin", ana)
    lab.access.request_control("twin", ben)
    run = lab.runs.start("twin", ana, lab_request(samples=500))
    step_clock.allow(20.0)
    until(lambda: lab.runs.get(run.id, ana).samples_taken == 21)
    assert lab.access.view("twin", ana).access.idle_time_left is None  # a run is activity
    lab.access.extend("twin", tina, -300)  # the turn is cut short
    step_clock.allow(math.inf)
    lab.runs.wait("twin", timeout=30)
    done = lab.runs.get(run.id, ana)
    assert (done.status, done.end_reason) == ("stopped", "ended by end of the turn at the controls")
    assert done.results["lsm"]["final"] is True  # END computes the final estimates
    assert lab.access.view("twin", ben).access.role == "controller"


def test_a_rig_fault_fails_the_run_and_ends_the_turn(make_lab: LabFactory) -> None:
    twins: dict[str, TwinRig] = {}

    def opener(rig: RigConfig) -> Rig:
        twins[rig.id] = TwinRig("paper", clock=VirtualClock())
        return twins[rig.id]

    lab = make_lab(opener=opener)
    ana, tina = person(lab, "ana"), person(lab, "tina", "teacher")
    lab.access.request_control("twin", ana)
    twins["twin"].inject_fault("sensor unplugged", at=30.0)
    run = lab.runs.start("twin", ana, lab_request(samples=100))
    lab.runs.wait("twin", timeout=30)
    done = lab.runs.get(run.id, ana)
    assert done.status == "failed"
    assert "sensor unplugged" in (done.end_reason or "")
    view = lab.access.view("twin", ana)
    assert (view.state, view.access.role) == ("fault", "watcher")
    assert lab.access.history("twin")[0].end_reason == "rig_fault"
    lab.set_service("twin", tina, True)
    assert lab.access.request_control("twin", ana).state == "in_use"


def test_a_restart_marks_a_running_run_interrupted(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = twin_lab(make_lab, step_clock)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, lab_request(samples=100))
    step_clock.allow(9.0)
    until(lambda: stored_samples(lab, run.id) == 10)
    restarted = make_lab()  # a new server on the same database, the old one gone
    record = restarted.runs.get(run.id, ana)
    assert (record.status, record.end_reason) == (
        "interrupted",
        "the server stopped during the run",
    )
    assert record.samples_stored == 10  # nothing stored was lost
    closing = threading.Thread(target=lab.close)  # the old process ends: its run is aborted
    closing.start()
    step_clock.allow(math.inf)
    closing.join(timeout=30)
    assert lab.runs.running("twin") is None
    assert restarted.runs.get(run.id, ana).status == "interrupted"


def test_runs_are_private_to_their_owner_and_visible_to_teachers(make_lab: LabFactory) -> None:
    lab = twin_lab(make_lab)
    ana, ben = person(lab, "ana"), person(lab, "ben")
    tina = person(lab, "tina", "teacher")
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, lab_request(samples=20))
    lab.runs.wait("twin", timeout=30)
    with pytest.raises(Exception, match=f"run {run.id} belongs to another user"):
        lab.runs.get(run.id, ben)
    with pytest.raises(Exception, match="no run 999"):
        lab.runs.get(999, tina)
    assert [r.id for r in lab.runs.list(ana)] == [run.id]
    assert lab.runs.list(ben) == []
    assert [r.username for r in lab.runs.list(tina, "twin")] == ["ana"]
    assert lab.runs.list(tina, "other") == []


def test_a_run_needs_a_device(lab: Lab) -> None:
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    with pytest.raises(Exception, match="has no device attached"):
        lab.runs.start("twin", ana, lab_request())


def lab_request(
    *, samples: int = 100, signal: str | None = "square:4:6:0.1", setpoint: float | None = None
) -> RunRequest:
    return RunRequest(
        dt=1.0, samples=samples, signal=signal, setpoint=setpoint, methods=("lsm", "wlsm")
    )
