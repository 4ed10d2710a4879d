"""The rig's typical dead time reaches the block and recursive identifiers of a run."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from thermolab.ident import IdentificationWarning
from thermolab.ident.registry import SETTINGS
from thermolab.lab.runs.request import (
    LIVE_DEAD_TIME_METHODS,
    RunRequest,
    live_dead_time,
    plan_run,
)
from thermolab.rigs import RigSpec
from thermolab.simulation import simulate_first_order

METHODS = ("lsm", "blockls", "malsm", "wlsm")


def test_live_dead_time_methods_are_the_registrys_searched_trajectories() -> None:
    assert SETTINGS["order"].structural_default is not None
    assert LIVE_DEAD_TIME_METHODS == ("blockls", "malsm", "wlsm")


def test_the_twins_run_keeps_the_papers_order() -> None:
    """``sim`` (the paper's twin) has no dead time: the identifiers keep (1, 1, 0)."""
    request = RunRequest(dt=1.0, samples=400, signal="square:4:6:0.1", methods=METHODS)
    plan = plan_run(request, (0.0, 10.0), RigSpec.parse("sim").typical_dead_time)
    for m in LIVE_DEAD_TIME_METHODS:
        assert plan.settings["dead_time"][m] == {"handling": "rig", "delay": 0, "theta": 0.0}
        assert plan.identifiers[m].params["order"] == {"na": 1, "nb": 1, "delay": 0}
    assert plan.identifiers["lsm"].params["order"] is None  # searched at END


@pytest.mark.parametrize("dt", [1.0, 2.0])
def test_a_tclab_run_gives_the_rigs_dead_time_and_reports_it(dt: float) -> None:
    """``sim:tclab`` declares 16 s: 16 samples at 1 s, 8 at 2 s; the END estimate
    of a plant with that dead time carries theta = 16 s and the right gain."""
    theta = RigSpec.parse("sim:tclab").typical_dead_time
    assert theta == 16.0
    samples = int(3000 / dt)
    request = RunRequest(
        dt=dt, samples=samples, signal="square:2:8:0.01", methods=METHODS, window=200
    )
    plan = plan_run(request, (0.0, 10.0), theta)
    delay = round(theta / dt)
    k = np.arange(samples)
    u = np.where((k * dt // 100) % 2 == 0, 8.0, 2.0)
    y = simulate_first_order(u, 0.5, 150.0, dt, ambient=0.0, theta=theta)
    for m in LIVE_DEAD_TIME_METHODS:
        assert plan.settings["dead_time"][m] == {
            "handling": "rig", "delay": delay, "theta": delay * dt,
        }  # fmt: skip
        ident = plan.identifiers[m]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentificationWarning)
            for uk, yk in zip(u, y, strict=True):
                ident.update(float(uk), float(yk))
            final = ident.finish()
        assert final is not None
        assert final.extras["theta"] == pytest.approx(theta)
        assert abs(final.K / 0.5 - 1.0) < 1e-3


def test_a_short_window_shortens_the_delay_it_is_given() -> None:
    request = RunRequest(dt=1.0, samples=400, methods=("malsm", "blockls"), window=12, block=100)
    assert live_dead_time(request, "malsm", 16.0) == 7
    assert live_dead_time(request, "blockls", 16.0) == 16
    assert live_dead_time(request, "lsm", 16.0) == 0
    plan = plan_run(request, (0.0, 10.0), 16.0)
    assert plan.identifiers["malsm"].params["order"] == {"na": 1, "nb": 1, "delay": 7}
