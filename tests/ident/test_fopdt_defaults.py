"""Dead time right by default (issue #8 item 4): the FOPDT-equivalent θ on the kit twin."""

from __future__ import annotations

import contextlib
import csv
import io
import warnings
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.cli import main as thermolab
from thermolab.ident import (
    ArxOrder,
    IdentificationWarning,
    block_least_squares,
    least_squares,
    moving_window_least_squares,
    weighted_least_squares,
)
from thermolab.ident.deadtime import input_repeat, search_delay
from thermolab.simulation import simulate_first_order

#: The kit model of the ``sim:tclab`` twin (benchmarks/bench_fopdt.py fits it):
#: the FOPDT whose θ absorbs the twin's 3 s sensor lag besides its 13 s transport delay.
KIT_K, KIT_TAU, KIT_THETA = 0.600, 140.1, 15.9


def twin_step_record(folder: Path, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``thermolab run`` on the ``sim:tclab`` twin: 0 → 50 % at t = 20 s, 1500 samples."""
    out = folder / f"tclab-{seed}.csv"
    argv = [
        "run", "--rig", "sim:tclab", "--signal", "step:0:50@20", "--samples", "1500",
        "--fast", "--seed", str(seed), "--method", "lsm", "--out", str(out), "--json",
    ]  # fmt: skip
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert thermolab(argv) == 0
    with out.open() as f:
        rows = list(csv.DictReader(f))
    return np.array([float(r["u"]) for r in rows]), np.array([float(r["y"]) for r in rows])


def test_lsm_default_dead_time_is_the_kit_models_on_the_twin(tmp_path: Path) -> None:
    """The one-step delay stops at the first visible response (12 s, -25 %); the default
    (least simulation error from there) gives the FOPDT θ, with K and tau, within 5 % over
    three seeds (θ in whole samples: 15 or 16 s each)."""
    found = []
    for seed in (1, 2, 3):
        u, y = twin_step_record(tmp_path, seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentificationWarning)
            r = least_squares(u, y, 1.0)
        assert r.delay_search is not None
        assert r.delay_search.criterion.startswith("least free-run simulation error")
        assert abs(r.theta - KIT_THETA) <= 0.05 * KIT_THETA + 1.0
        found.append((r.K, r.tau, r.theta))
        first_response = search_delay(u, y, r.offset, 60, "one-step").delay
        assert first_response * 1.0 < 0.9 * KIT_THETA  # what the default was before
    for value, kit in zip(np.mean(found, axis=0), (KIT_K, KIT_TAU, KIT_THETA), strict=True):
        assert abs(value / kit - 1.0) <= 0.05


def test_a_square_waves_repeat_bounds_the_delays_tried() -> None:
    square = np.where((np.arange(3000) // 50) % 2 == 0, 6.0, 4.0)
    assert input_repeat(square, 60) == (48, 25)
    assert input_repeat(np.r_[np.zeros(20), np.full(1000, 5.0)], 60) is None
    rng = np.random.default_rng(3)
    y = simulate_first_order(square, 0.6, 140.0, 1.0, theta=10.0) + rng.normal(0, 0.01, 3000)
    s = search_delay(square, y, "initial", 60, "simulation")
    assert s.repeat == 48
    assert s.delays[-1] == 25
    assert abs(s.delay - 10) <= 1  # a sample of noise


@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    half_period=st.integers(20, 55),
    delay=st.integers(0, 4),
)
def test_a_periodic_input_never_gets_a_delay_aliased_with_its_repeat(
    seed: int, half_period: int, delay: int
) -> None:
    """Domain: square waves of half-period 20..55 samples (a repeat within the 60 delays
    tried), 0..4 samples of dead time, noise that hides the ripple's detail. Default LSM
    never picks a delay past a quarter period (the half period is the input's repeat,
    where a sign-flipped gain fits as well) and the gain keeps its sign."""
    rng = np.random.default_rng(seed)
    n = 4000
    u = np.where((np.arange(n) // half_period) % 2 == 0, 6.0, 4.0)
    y = simulate_first_order(u, 0.14, 250.0, 1.0, theta=float(delay))
    y = y + rng.normal(0.0, 0.005, n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        r = least_squares(u, y, 1.0, offset="initial")
    assert r.delay_search is not None
    assert r.delay_search.repeat is not None
    assert r.order.delay < r.delay_search.repeat // 2 + 1
    assert r.K > 0.0


def test_block_and_recursive_methods_search_the_dead_time_and_flag_a_settled_end(
    tmp_path: Path,
) -> None:
    """On the twin's step, blockls, malsm and wlsm take the record's dead time (the same
    criterion as LSM) and say their final estimate, on the settled tail, is not excited
    (it was τ ≈ 0.5 s, shown valid) instead of showing it as trusted."""
    u, y = twin_step_record(tmp_path, 1)
    for method in (block_least_squares, moving_window_least_squares, weighted_least_squares):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", IdentificationWarning)
            tr = method(u, y, 1.0)
        assert any("final estimate not excited" in str(w.message) for w in caught)
        assert any(w.startswith("final estimate not excited") for w in tr.warnings)
        assert tr.params["dead_time"] == "searched"
        assert abs(tr.params["delay"] - KIT_THETA) <= 0.05 * KIT_THETA + 1.0
        assert not tr.trusted
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentificationWarning)
            given = method(u, y, 1.0, order=ArxOrder(1, 1, 4), offset="initial")
        assert (given.params["dead_time"], given.params["delay"]) == ("given", 4)


def test_a_step_on_an_fopdt_plant_keeps_every_estimate_exact_and_unflagged() -> None:
    """Noise-free FOPDT, a square wave through the record: the searched delay is exact,
    every window's estimate is the plant, and nothing is flagged."""
    u = np.where((np.arange(1500) // 100) % 2 == 0, 50.0, 20.0)
    y = simulate_first_order(u, 0.6, 140.0, 1.0, ambient=21.0, theta=12.0)
    tr = moving_window_least_squares(u, y, 1.0, window=150)
    assert tr.params["delay"] == 12
    assert tr.trusted
    np.testing.assert_allclose([tr.final.K, tr.final.tau], [0.6, 140.0], rtol=1e-6)


def test_only_a_separate_delay_within_the_margin_is_a_tie() -> None:
    """Neighbours of the best delay within the margin are one answer (a flat minimum);
    a delay within it past a worse one is a second answer, which the search warns of."""
    from thermolab.ident.deadtime import _separate_ties

    sse = np.array([5.0, 1.0, 1.001, 3.0, 1.002, 4.0])
    assert _separate_ties(sse, 1, 1.005) == [4]
    assert _separate_ties(sse, 1, 1.0015) == []
    assert _separate_ties(np.array([np.inf, 1.0, np.inf]), 1, 1.0) == []
