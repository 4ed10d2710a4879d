"""Trajectory: alignment, converged_at, stats, to_dict, plot."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from thermolab.errors import InvalidParameterError
from thermolab.ident import ArxOrder, FirstOrderModel, Trajectory, block_least_squares
from thermolab.simulation import REFERENCE_MODEL


def trajectory_of_gains(K: list[float], tau: float = 10.0) -> Trajectory:
    """A first-order trajectory whose gain follows ``K`` (NaN: no estimate) at fixed tau."""
    a = math.exp(-1.0 / tau)
    gains = np.array(K, dtype=float)
    W = np.column_stack([np.where(np.isnan(gains), np.nan, a), (1 - a) * gains])
    return Trajectory("wlsm", 1.0, W, ArxOrder(), "initial", ("a", "b"))


def test_converged_at_is_the_first_sample_of_the_final_stretch_inside_the_band() -> None:
    K = [0.5, 2.0, 1.5, 1.0, 1.005, 0.998, 1.0, 1.0]
    tr = trajectory_of_gains(K)
    # stabilisation value: mean of the last 4 = 1.00075; band ±1 % = [0.9907, 1.0108]
    assert tr.converged_at(tol=0.01, last=4) == {"K": 3, "tau": 0}
    # a tighter band: 1.005 is out, so the stretch starts after it
    assert tr.converged_at(tol=0.003, last=4)["K"] == 5


def test_converged_at_is_none_when_the_last_estimate_is_outside() -> None:
    tr = trajectory_of_gains([1.0, 1.0, 1.0, 1.0, 3.0])
    assert tr.converged_at(tol=0.01, last=5)["K"] is None


def test_converged_at_skips_rows_without_an_estimate() -> None:
    nan = math.nan
    tr = trajectory_of_gains([nan, nan, 2.0, nan, nan, 1.0, nan, nan, 1.0])
    # Rows with no estimate (before the first and between blocks) neither break
    # nor make convergence: it starts at the first in-band estimate, sample 5.
    assert tr.converged_at(tol=0.01, last=4) == {"K": 5, "tau": 2}


def test_an_invalid_estimate_breaks_convergence() -> None:
    tr = trajectory_of_gains([1.0, 1.0, 1.0, 1.0, 1.0])
    W = tr.W.copy()
    W[3, 0] = 1.2  # unstable at sample 3
    tr2 = Trajectory("wlsm", 1.0, W, ArxOrder(), "initial", ("a", "b"))
    assert not tr2.valid[3]
    assert tr2.converged_at(last=5) == {"K": 4, "tau": 4}


def test_stats_over_the_last_samples_ignore_missing_and_invalid_rows() -> None:
    nan = math.nan
    tr = trajectory_of_gains([5.0, nan, 1.0, 2.0, nan, 3.0])
    s = tr.stats(last=5)
    assert s["K"] == pytest.approx({"mean": 2.0, "max": 3.0, "min": 1.0}, rel=1e-12)
    assert s["tau"]["mean"] == pytest.approx(10.0, rel=1e-12)
    empty = trajectory_of_gains([nan, nan]).stats()
    assert math.isnan(empty["K"]["mean"])


def test_stats_and_convergence_of_the_paper_block_run() -> None:
    """LSM(3): 20 block estimates, stats over the 2000 samples = over the 20 blocks."""
    u = np.where((np.arange(2000) // 5) % 2 == 0, 6.0, 4.0)
    tr = block_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, block=100)
    s = tr.stats(last=2000)
    assert_allclose(s["K"]["mean"], np.mean(tr.K[tr.valid]), rtol=1e-15)
    assert tr.converged_at() == {"K": 99, "tau": 99}


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [({"tol": 0.0}, "tol"), ({"tol": -1.0}, "tol"), ({"last": 0}, "last"), ({"last": 2.5}, "last")],
)
def test_bad_convergence_arguments(kwargs: dict[str, float], fragment: str) -> None:
    with pytest.raises(InvalidParameterError, match=fragment):
        trajectory_of_gains([1.0, 1.0]).converged_at(**kwargs)  # type: ignore[arg-type]


def test_alignment_reasons_and_final() -> None:
    nan = math.nan
    W = np.array([[nan, nan], [0.9, 0.2], [1.3, 0.1], [-0.5, 0.1]])
    status = np.array([0, 0, 0, 0], dtype=np.int8)
    tr = Trajectory("malsm", 2.0, W, ArxOrder(), 0.5, ("a", "b"), status=status)
    assert tr.k.tolist() == [0, 1, 2, 3]
    assert tr.first_estimate == 1
    assert tr.valid.tolist() == [False, True, False, False]
    reasons = tr.invalid_reason
    assert reasons[0].startswith("no estimate yet")
    assert reasons[1] is None
    assert reasons[2].startswith("unstable")
    assert "dominant pole <= 0" in reasons[3]
    assert_allclose([tr.K[1], tr.tau[1]], [2.0, -2.0 / math.log(0.9)], rtol=1e-14)
    assert not tr.final.valid
    assert tr.final.reason == reasons[3]


def test_to_dict_round_trips_through_json() -> None:
    u = np.where((np.arange(400) // 5) % 2 == 0, 6.0, 4.0)
    tr = block_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, block=100)
    d = tr.to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert d["method"] == "blockls"
    assert d["params"] == {"block": 100, "dead_time": "searched", "delay": 0}
    assert d["K"][:99] == [None] * 99
    assert d["converged_at"] == {"K": 99, "tau": 99}
    assert d["final"]["valid"] is True
    short = tr.to_dict(arrays=False)
    assert "K" not in short
    assert short["stats"]["tau"]["min"] == pytest.approx(250.126233, abs=1e-6)


def test_plot_draws_the_parameter_convergence() -> None:
    pytest.importorskip("matplotlib")
    tr = trajectory_of_gains([0.5, 0.9, 1.0, 1.0])
    fig = tr.plot(reference=FirstOrderModel(1.0, 10.0))
    ax_k, ax_tau = fig.axes
    assert ax_k.get_ylabel().startswith("K")
    assert ax_tau.get_ylabel().startswith("tau")
    assert len(ax_k.lines) == 2  # estimate and reference
