"""A run declares its length; the turn covers it; START refuses one longer than the rig allows.

The lab's clock is a :class:`ManualClock` and the twin's a :class:`StepClock`,
so that a 2000-s run passes in a fraction of a second of real time.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from datetime import timedelta

import numpy as np
import pytest

from thermolab.errors import InvalidParameterError
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import RigConfig
from thermolab.lab.runs import RunRequest
from thermolab.lab.runs.timing import JITTER_LIMIT, timing_summary
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig

from .conftest import LabFactory
from .test_runs import StepClock, api_client, person, until

# On SQLite alone: the turn covers the run: clock rules (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only


@pytest.fixture
def step_clock() -> Iterator[StepClock]:
    clock = StepClock()
    yield clock
    clock.allow(math.inf)  # never leave a run blocked behind a test


def stepped_lab(make_lab: LabFactory, clock: StepClock, **rig_options: object) -> Lab:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=clock)

    return make_lab(opener=opener, **rig_options)


PAPER_RUN = RunRequest(dt=1.0, samples=2000, signal="step:0:4@10", methods=("srm", "lsm"))


def test_the_papers_2000_sample_run_ends_under_the_default_limits(
    make_lab: LabFactory, step_clock: StepClock, clock: ManualClock
) -> None:
    lab = stepped_lab(make_lab, step_clock)
    rig = lab.config.rig("twin")
    assert rig == RigConfig("twin", "Twin", "sim")  # the default limits
    assert rig.control_time_limit < 2000 <= rig.max_run_seconds
    ana, ben = person(lab, "ana"), person(lab, "ben")
    lab.access.request_control("twin", ana)
    lab.access.request_control("twin", ben)
    run = lab.runs.start("twin", ana, PAPER_RUN)
    assert run.ends_at is not None
    assert run.ends_at - run.started_at == timedelta(seconds=2000)
    # The queue's estimate counts the run, not only the turn's 300 s.
    assert lab.access.view("twin", ben).access.estimated_time_until_control == pytest.approx(
        2000.0, abs=1e-6
    )
    for t in range(10, 2001, 10):  # real time passes; both clients keep in touch
        clock.advance(10)
        lab.access.heartbeat("twin", ana)
        lab.access.heartbeat("twin", ben)
        lab.sweep()
        assert lab.access.view("twin", ana).access.role == "controller"
        step_clock.allow(min(t, 1999))
        until(lambda t=t: lab.runs.get(run.id, ana).samples_taken >= min(t, 1999) + 1)
    lab.runs.wait("twin", timeout=30)
    done = lab.runs.get(run.id, ana)
    assert (done.status, done.samples_stored) == ("finished", 2000)
    # A twin's data are exact: timed by its own axis, no wall-clock lateness, no warning.
    assert done.timing is not None
    assert (done.timing["rig"], done.timing["maxLateness"]) == ("twin", None)
    assert done.timing["periodSpread"] == pytest.approx(0.0, abs=1e-12)
    assert done.timing["warnings"] == []
    # The turn's time ran out long ago: it ends once the run is over.
    lab.sweep()
    assert lab.access.view("twin", ben).access.role == "controller"


def test_a_run_longer_than_the_rig_allows_is_refused_with_the_longest_allowed(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = stepped_lab(make_lab, step_clock, max_run_seconds=600.0)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    too_long = RunRequest(dt=0.5, samples=1201, signal="step:0:4@10", methods=("lsm",))
    message = (
        "a run of 1201 samples at dt = 0.5 s lasts 600.5 s, longer than rig 'twin' allows "
        "(600 s): at this dt at most 1200 samples"
    )
    with pytest.raises(
        InvalidParameterError, match=message.replace("(", r"\(").replace(")", r"\)")
    ):
        lab.runs.start("twin", ana, too_long)
    assert lab.runs.running("twin") is None
    run = lab.runs.start("twin", ana, RunRequest(dt=0.5, samples=1200, methods=("lsm",)))
    assert run.ends_at is not None
    assert run.ends_at - run.started_at == timedelta(seconds=600)
    lab.runs.stop("twin", ana)
    step_clock.allow(math.inf)
    lab.runs.wait("twin", timeout=30)


def test_a_real_rigs_timing_shows_its_lateness_and_warns_on_a_spread_period() -> None:
    rng = np.random.default_rng(8)
    t = np.arange(600.0)
    lateness = rng.uniform(0.0, 0.2, t.size)
    real = timing_summary(t + lateness, lateness, 1.0, simulated=False)
    assert real["rig"] == "real"
    assert real["maxLateness"] == pytest.approx(lateness.max(), rel=1e-12)
    assert real["p95Lateness"] == pytest.approx(np.percentile(lateness, 95), rel=1e-12)
    assert real["periodSpread"] > JITTER_LIMIT
    assert real["warnings"][0].startswith("timing jitter: the sample period spreads")
    steady = timing_summary(t + 0.01, np.full(t.size, 0.01), 1.0, simulated=False)
    assert steady["warnings"] == []
    assert steady["maxLateness"] == pytest.approx(0.01, rel=1e-12)
    # A twin: wall-clock lateness is no part of its data; its readings' times are exact...
    twin = timing_summary(t, lateness, 1.0, simulated=True)
    assert (twin["rig"], twin["maxLateness"], twin["warnings"]) == ("twin", None, [])
    # ...unless its preset simulates jitter: then it warns like a real rig.
    jittery = timing_summary(t + lateness, lateness, 1.0, simulated=True)
    assert jittery["maxLateness"] is None
    assert jittery["warnings"][0].startswith("timing jitter")


def test_a_too_long_run_is_a_422_with_the_reason(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = stepped_lab(make_lab, step_clock, max_run_seconds=100.0)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    with api_client(lab, "ana") as client:
        response = client.post(
            "/api/rigs/twin/runs", json={"dt": 1, "samples": 101, "methods": ["lsm"]}
        )
    assert response.status_code == 422, response.text
    body = response.json()
    assert "longer than rig 'twin' allows (100 s): at this dt at most 100 samples" in body["detail"]
    assert body["code"] == "invalid_parameter"
