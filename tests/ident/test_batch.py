"""Batch least squares (LSM) and block least squares (LSM(2)/(3))."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from thermolab.errors import (
    InsufficientExcitationError,
    InvalidDataError,
    InvalidParameterError,
)
from thermolab.ident import (
    ArxOrder,
    IdentificationWarning,
    block_least_squares,
    least_squares,
)
from thermolab.simulation import REFERENCE_MODEL, simulate_arx, simulate_first_order


def square(n: int, low: float, high: float, half_period: int = 5) -> np.ndarray:
    """The paper's Automatic square wave: ``high`` first, then ``low``, every half period."""
    return np.where((np.arange(n) // half_period) % 2 == 0, high, low)


def exciting_input(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random levels in ±10 V held for random stretches: exciting for any low order."""
    out = np.empty(n)
    k = 0
    while k < n:
        hold = int(rng.integers(3, 40))
        out[k : k + hold] = rng.uniform(-10.0, 10.0)
        k += hold
    return out


# -- the paper's Table I rows that batch least squares must match ----------------------


def test_lsm1_reproduces_table_one() -> None:
    u = np.full(2000, 10.0)
    r = least_squares(u, REFERENCE_MODEL.simulate(u), 1.0)
    assert f"{r.K:.6f}" == "0.140090"
    assert f"{r.tau:.6f}" == "250.126233"
    assert r.model.valid
    assert_allclose(r.fit_one_step, 100.0, atol=1e-6)
    assert_allclose(r.fit_simulation, 100.0, atol=1e-6)


def test_lsm3_reproduces_table_one_at_every_block() -> None:
    u = square(2000, 4.0, 6.0)
    tr = block_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, block=100)
    assert tr.valid.sum() == 20
    assert np.flatnonzero(tr.valid).tolist() == list(range(99, 2000, 100))
    for value in tr.K[tr.valid]:
        assert f"{value:.6f}" == "0.140090"
    for value in tr.tau[tr.valid]:
        assert f"{value:.6f}" == "250.126233"


def test_lsm2_blocks_of_a_step_are_exact_in_double_precision() -> None:
    """A solve without normal equations keeps even the settled blocks to ~1e-8 s."""
    u = np.full(2000, 10.0)
    tr = block_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, block=100)
    s = tr.stats()
    assert_allclose([s["tau"]["min"], s["tau"]["max"]], 250.126233, atol=1e-5)
    assert_allclose([s["K"]["min"], s["K"]["max"]], 0.140090, rtol=1e-9)


# -- laws ----------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    a=st.floats(0.05, 0.995),
    K=st.floats(0.01, 5.0) | st.floats(-5.0, -0.01),
    ambient=st.floats(-5.0, 5.0),
    n=st.integers(60, 800),
    offset=st.sampled_from(["initial", "fit", "known"]),
)
def test_noise_free_data_recover_the_exact_first_order_model(
    seed: int, a: float, K: float, ambient: float, n: int, offset: str
) -> None:
    rng = np.random.default_rng(seed)
    u = exciting_input(rng, n)
    tau = -1.0 / math.log(a)
    y = simulate_first_order(u, K, tau, 1.0, ambient=ambient)
    with warnings.catch_warnings():
        # tau under two sample periods is flagged (a = 0.05 .. 0.135 here); checked below.
        warnings.simplefilter("ignore", IdentificationWarning)
        r = least_squares(u, y, 1.0, offset=ambient if offset == "known" else offset)
    assert r.model.valid
    assert r.order.delay == 0
    assert any("implausible time constant" in w for w in r.warnings) == (tau < 2.0)
    assert_allclose(r.W[:2], [a, (1 - a) * K], rtol=1e-8, atol=1e-11)
    assert_allclose(r.K, K, rtol=1e-7)
    assert_allclose(r.tau, tau, rtol=1e-7)
    assert_allclose(r.ambient, ambient, atol=1e-7 * (1 + abs(ambient)))


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    p1=st.floats(0.3, 0.97),
    ratio=st.floats(0.05, 0.9),
    delay=st.integers(0, 3),
    ambient=st.floats(-3.0, 3.0),
)
def test_noise_free_data_recover_an_arx_model(
    seed: int, p1: float, ratio: float, delay: int, ambient: float
) -> None:
    rng = np.random.default_rng(seed)
    p2 = p1 * ratio
    a = (p1 + p2, -p1 * p2)
    b = (0.3, 0.1)  # zero at -1/3: never cancels a (positive) pole, so W is identifiable
    u = exciting_input(rng, 600)
    y = simulate_arx(u, a, b, delay=delay, ambient=ambient)
    order = ArxOrder(2, 2, delay)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)  # tau < 2 dt is flagged
        r = least_squares(u, y, 2.0, order=order)
    assert_allclose(r.W, [*a, *b], rtol=1e-7, atol=1e-10)
    assert r.model.valid
    assert_allclose(r.K, sum(b) / (1 - sum(a)), rtol=1e-7)
    assert_allclose(r.tau, -2.0 / math.log(p1), rtol=1e-7)


def test_offset_modes_on_a_record_that_starts_warm() -> None:
    u = square(3000, 0.0, 4.0)
    y = REFERENCE_MODEL.simulate(u) + 2.5
    for offset in ("initial", "fit", 2.5):
        r = least_squares(u, y, 1.0, offset=offset)
        assert_allclose([r.K, r.tau], [0.140090, 250.126233], rtol=1e-8)
        assert_allclose(r.ambient, 2.5, rtol=1e-8)
    fit = least_squares(u, y, 1.0, offset="fit")
    assert fit.param_names == ("a", "b", "c")
    assert_allclose(fit.W[2], 2.5 * (1 - fit.W[0]), rtol=1e-8)
    # The paper's raw form reads the ambient as part of the dynamics: biased.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        raw = least_squares(u, y, 1.0, offset="none")
    assert any(w.startswith("residual test failed") for w in raw.warnings)
    assert abs(raw.K - 0.140090) > 0.01 or not raw.model.valid


def test_standard_errors_match_the_scatter_of_the_estimates() -> None:
    """With white equation error (the ARX noise model) the reported stderr is the spread."""
    u = square(800, 0.0, 8.0, half_period=40)
    a, b = REFERENCE_MODEL.a, REFERENCE_MODEL.b
    results = []
    for seed in range(200):
        e = 0.002 * np.random.default_rng(seed).standard_normal(u.size)
        y = np.empty(u.size)
        y[0] = 0.0
        for k in range(u.size - 1):
            y[k + 1] = a * y[k] + b * u[k] + e[k]
        with warnings.catch_warnings():
            # 200 runs of a 99 % residual test: about two fail by chance.
            warnings.simplefilter("ignore", IdentificationWarning)
            results.append(least_squares(u, y, 1.0, order=ArxOrder(), offset="initial"))
    W = np.array([r.W for r in results])
    K = np.array([r.K for r in results])
    tau = np.array([r.tau for r in results])
    assert_allclose(W.std(axis=0), np.median([r.stderr for r in results], axis=0), rtol=0.2)
    assert_allclose(K.std(), np.median([r.K_stderr for r in results]), rtol=0.2)
    assert_allclose(tau.std(), np.median([r.tau_stderr for r in results]), rtol=0.25)


def test_diagnostics_and_json() -> None:
    rng = np.random.default_rng(7)
    u = square(1500, 0.0, 5.0, half_period=100)
    y = REFERENCE_MODEL.simulate(u) + 1.0 + 1e-3 * rng.standard_normal(u.size)
    # Measurement noise on an ARX model leaves coloured residuals: flagged, with the cause.
    with pytest.warns(IdentificationWarning, match="residuals are not white"):
        r = least_squares(u, y, 1.0)
    assert r.n_samples == 1500
    assert r.n_rows == 1499
    assert r.k[0] == 1
    assert r.k[-1] == 1499
    assert_allclose(r.residuals, r.y_measured - r.y_one_step, rtol=0, atol=1e-15)
    assert r.cond >= r.cond_scaled >= 1.0 or r.cond_scaled >= 1.0
    assert 90.0 < r.fit_one_step <= 100.0
    assert 50.0 < r.fit_simulation <= 100.0
    d = r.to_dict(arrays=True)
    assert json.loads(json.dumps(d)) == d
    assert d["method"] == "lsm"
    assert d["valid"] is True
    assert d["trusted"] is False
    assert d["theta"] == 0.0
    assert d["operating_point"]["handling"] == "initial"
    assert len(d["residuals"]) == 1499


def test_an_unstable_estimate_is_a_flagged_result_not_an_error() -> None:
    u = np.ones(50)
    y = 1.01 ** np.arange(50.0)  # grows without bound: a = 1.01
    r = least_squares(u, y, 1.0, offset="none")
    assert not r.model.valid
    assert r.model.reason is not None
    assert ">= 1" in r.model.reason
    assert math.isnan(r.K)
    assert math.isnan(r.tau_stderr)
    assert r.to_dict()["K"] is None


def test_plot_returns_a_figure() -> None:
    pytest.importorskip("matplotlib")
    u = square(400, 0.0, 4.0)
    fig = least_squares(u, REFERENCE_MODEL.simulate(u), 1.0).plot()
    assert len(fig.axes) == 2


# -- errors --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("u", "y", "error", "fragment"),
    [
        ([1.0, np.nan, 1.0, 1.0], [0.0, 0.1, 0.2, 0.3], InvalidDataError, "u must be finite"),
        ([1.0, 1.0, 1.0, 1.0], [0.0, np.inf, 0.2, 0.3], InvalidDataError, "y must be finite"),
        ([1.0, 1.0, 1.0], [0.0, 0.1, 0.2, 0.3], InvalidDataError, "same number of samples"),
        ([1.0, 2.0], [0.0, 0.1], InvalidDataError, "too few samples"),
        ([[1.0, 2.0]], [[0.0, 0.1]], InvalidDataError, "one-dimensional"),
        (["a", "b", "c"], [0.0, 0.1, 0.2], InvalidDataError, "numbers"),
    ],
)
def test_bad_records_are_refused_with_the_reason(
    u: object, y: object, error: type[Exception], fragment: str
) -> None:
    with pytest.raises(error, match=fragment):
        least_squares(u, y, 1.0)  # type: ignore[arg-type]


def test_input_kept_at_zero_is_no_excitation() -> None:
    y = np.full(100, 2.0)
    with pytest.raises(InsufficientExcitationError, match="input is kept at 0 V") as info:
        least_squares(np.zeros(100), y, 1.0)
    assert "DᵀD is singular" in str(info.value)


def test_settled_output_is_no_excitation() -> None:
    with pytest.raises(InsufficientExcitationError, match="held constant at 5 V"):
        least_squares(np.full(100, 5.0), np.full(100, 0.7), 1.0, offset="none")


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"dt": 0.0}, "dt"),
        ({"dt": -1.0}, "dt"),
        ({"offset": "ambient"}, "offset must be one of"),
        ({"offset": math.nan}, "offset"),
        ({"order": 3}, "order must be"),
        ({"order": (0, 1, 0)}, "na"),
    ],
)
def test_bad_parameters_are_refused(kwargs: dict[str, object], fragment: str) -> None:
    args: dict[str, object] = {"dt": 1.0}
    args.update(kwargs)
    u = square(50, 0.0, 1.0)
    with pytest.raises(InvalidParameterError, match=fragment):
        least_squares(u, REFERENCE_MODEL.simulate(u), **args)  # type: ignore[arg-type]


def test_block_parameters_and_partial_blocks() -> None:
    u = square(450, 4.0, 6.0)
    y = REFERENCE_MODEL.simulate(u)
    tr = block_least_squares(u, y, 1.0, block=100)
    assert tr.n_samples == 450
    assert int(tr.valid.sum()) == 4
    with pytest.raises(InvalidParameterError, match="block must be >= 3"):
        block_least_squares(u, y, 1.0, block=2)
    with pytest.raises(InvalidParameterError, match="block must be >= 4"):
        block_least_squares(u, y, 1.0, block=3, offset="fit")
    with pytest.raises(InvalidDataError, match="too few samples"):
        block_least_squares(u[:50], y[:50], 1.0, block=100)


def test_a_block_without_excitation_is_flagged_not_raised() -> None:
    u = np.concatenate([square(200, 0.0, 5.0), np.zeros(100)])
    y = REFERENCE_MODEL.simulate(u)
    y[200:] = y[200]  # a settled stretch: no information at all
    u[199] = 0.0
    tr = block_least_squares(u, y, 1.0, block=100, offset="none")
    assert tr.valid[99]
    assert tr.valid[199]
    assert tr.reason_code[299] == 2
    assert tr.invalid_reason[299].startswith("not excited")


# A last block of a few samples on a settled stretch is flagged as not excited
# (the noise-free estimate is still exact, which is what this law checks).
@pytest.mark.filterwarnings("ignore:final estimate not excited")
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), block=st.integers(4, 60), ambient=st.floats(-4, 4))
def test_every_block_recovers_noise_free_parameters(seed: int, block: int, ambient: float) -> None:
    rng = np.random.default_rng(seed)
    u = exciting_input(rng, 400)
    y = simulate_first_order(u, 1.3, 12.0, 1.0, ambient=ambient)
    tr = block_least_squares(u, y, 1.0, block=block)
    ok = tr.valid
    assert ok.any()
    assert_allclose(tr.K[ok], 1.3, rtol=1e-6)
    assert_allclose(tr.tau[ok], 12.0, rtol=1e-6)
