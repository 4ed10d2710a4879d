"""Moving-window (MALSM) and weighted (WLSM) least squares."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from thermolab.errors import InvalidDataError, InvalidParameterError
from thermolab.ident import (
    ArxOrder,
    IdentificationWarning,
    _kernels,
    _kernels_first_order,
    _regression,
    least_squares,
    moving_window_least_squares,
    weighted_least_squares,
)
from thermolab.simulation import PAPER_W0, REFERENCE_MODEL, simulate_arx, simulate_first_order

EPS = np.finfo(np.float64).eps


def square(n: int, low: float, high: float, half_period: int = 5) -> np.ndarray:
    return np.where((np.arange(n) // half_period) % 2 == 0, high, low)


def exciting_input(rng: np.random.Generator, n: int, max_hold: int = 40) -> np.ndarray:
    out = np.empty(n)
    k = 0
    while k < n:
        hold = int(rng.integers(1, max_hold))
        out[k : k + hold] = rng.uniform(-10.0, 10.0)
        k += hold
    return out


# -- MALSM ---------------------------------------------------------------------------


def test_malsm_reproduces_table_one_at_every_window() -> None:
    u = square(2000, 4.0, 6.0)
    tr = moving_window_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, window=100)
    assert tr.first_estimate == 99
    assert np.isnan(tr.K[:99]).all()
    assert tr.valid[99:].all()
    assert {f"{v:.6f}" for v in tr.K[99:]} == {"0.140090"}
    assert {f"{v:.6f}" for v in tr.tau[99:]} == {"250.126233"}


# Random plants include taus under two sample periods, which are flagged (not checked here).
@pytest.mark.filterwarnings("ignore::thermolab.ident.IdentificationWarning")
@settings(max_examples=30, deadline=None)
@example(seed=0, n=30, window=5, offset="fit", noise=0.0, every=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(30, 500),
    window=st.integers(4, 120),
    offset=st.sampled_from(["initial", "none", "fit", 1.5]),
    noise=st.sampled_from([0.0, 1e-4, 0.05]),
    every=st.sampled_from([None, 1]),
)
def test_every_malsm_estimate_equals_a_fresh_solve_of_its_window(
    seed: int, n: int, window: int, offset: str | float, noise: float, every: int | None
) -> None:
    """Law: each estimate is the least-squares solution of its window.

    The running normal equations (recomputed exactly every window, the
    default, or every row) agree with an SVD solve to within
    ``16 eps κ² ρ (|W_s| + |Y|)``: κ is the condition number of the window's
    regressor matrix with unit-norm columns, W_s the solution in those units,
    and ρ >= 1 how much larger (squared) the values that passed through the
    running sums lately (the two previous windows) were than the window's own
    mean square. Windows the kernel calls singular have κ² > 1e11.
    """
    rng = np.random.default_rng(seed)
    u = exciting_input(rng, n)
    y = simulate_first_order(u, rng.uniform(-3, 3) or 1.0, rng.uniform(1, 300), 1.0)
    y = y + rng.uniform(-5, 5) + noise * rng.standard_normal(n)
    if window > n or (offset == "fit" and window < 5):
        return
    tr = moving_window_least_squares(
        u, y, 1.0, window, order=ArxOrder(), offset=offset, recompute_every=every
    )
    reg = _regression.build(u, y, ArxOrder(), offset)
    Z = np.column_stack([reg.D, reg.Y])
    rows = window - 1
    assert np.isnan(tr.W[: window - 1]).all()
    for t in range(window - 1, n):
        r0 = t - window + 1
        D, Y = reg.D[r0 : r0 + rows], reg.Y[r0 : r0 + rows]
        norms = np.linalg.norm(D, axis=0)
        if (norms == 0).any():
            assert tr.reason_code[t] == 2
            continue
        s = np.linalg.svd(D / norms, compute_uv=False)
        # An exactly rank-deficient window (a few rows, a constant term) has s[-1] == 0.
        kappa2 = math.inf if s[-1] == 0.0 else (s[0] / s[-1]) ** 2
        if tr.reason_code[t] == 2:
            assert kappa2 > 1e11
            continue
        recent = Z[max(0, r0 - 2 * rows) : r0 + rows]
        mean_square = np.maximum(np.mean(Z[r0 : r0 + rows] ** 2, axis=0), 1e-300)
        rho = max(1.0, float(np.max(np.max(recent**2, axis=0) / mean_square)))
        W_ls = np.linalg.lstsq(D, Y, rcond=None)[0]
        err = np.linalg.norm((tr.W[t] - W_ls) * norms)
        scale = np.linalg.norm(W_ls * norms) + np.linalg.norm(Y)
        assert err <= 16 * EPS * kappa2 * rho * scale


def test_malsm_equals_batch_lsm_on_the_last_window() -> None:
    rng = np.random.default_rng(3)
    u = exciting_input(rng, 700)
    y = REFERENCE_MODEL.simulate(u) + 1e-3 * rng.standard_normal(700)
    tr = moving_window_least_squares(u, y, 1.0, window=200, offset=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)  # coloured residuals: noise
        last = least_squares(u[-200:], y[-200:], 1.0, order=ArxOrder(), offset=0.0)
    assert_allclose(tr.W[-1], last.W, rtol=1e-10)


def test_first_order_and_general_malsm_kernels_agree() -> None:
    rng = np.random.default_rng(11)
    u = exciting_input(rng, 3000)
    y = REFERENCE_MODEL.simulate(u) + 1e-3 * rng.standard_normal(3000)
    n = u.size
    out = []
    for first in (True, False):
        W = np.empty((n, 2), order="F")
        code = np.empty(n, dtype=np.int8)
        buf, sums, shift, ints = _kernels.malsm_state(49, 49, 2, first)
        if first:
            _kernels_first_order.malsm2_chunk(u, y, 1, n, buf, sums, ints, W, code)
        else:
            _kernels.malsm_chunk(u, y, 1, n, 1, 1, 0, False, buf, sums, shift, ints, W, code)
        out.append((W[1:], code[1:]))
    assert_array_equal(out[0][1], out[1][1])
    assert_allclose(out[0][0], out[1][0], rtol=1e-9, equal_nan=True)


def test_malsm_flags_windows_without_excitation() -> None:
    u = np.concatenate([square(300, 0.0, 5.0), np.full(300, 5.0)])
    y = REFERENCE_MODEL.simulate(u, y0=0.0)
    y[320:] = y[320]  # settled and constant: the window's columns become proportional
    tr = moving_window_least_squares(u, y, 1.0, window=50, offset="none")
    assert tr.valid[99]
    assert tr.reason_code[-1] == 2
    assert tr.invalid_reason[-1].startswith("not excited")


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ambient=st.floats(-5, 5), window=st.integers(20, 150))
def test_malsm_recovers_noise_free_parameters_at_every_window(
    seed: int, ambient: float, window: int
) -> None:
    rng = np.random.default_rng(seed)
    u = exciting_input(rng, 400, max_hold=8)
    y = simulate_first_order(u, 0.8, 30.0, 1.0, ambient=ambient)
    tr = moving_window_least_squares(u, y, 1.0, window)
    assert tr.valid[window - 1 :].all()
    assert_allclose(tr.K[window - 1 :], 0.8, rtol=1e-6)
    assert_allclose(tr.tau[window - 1 :], 30.0, rtol=1e-6)


def test_malsm_arx_order() -> None:
    rng = np.random.default_rng(5)
    u = exciting_input(rng, 600, max_hold=10)
    a, b = (1.3, -0.4), (0.2, 0.1)
    y = simulate_arx(u, a, b, delay=2, ambient=1.0)
    tr = moving_window_least_squares(u, y, 1.0, 60, order=ArxOrder(2, 2, 2))
    first = 60 - 1
    assert tr.first_estimate == first
    assert_allclose(tr.W[first:], np.tile([*a, *b], (600 - first, 1)), rtol=1e-7, atol=1e-10)
    assert_allclose(tr.K[first:], 0.3 / 0.1, rtol=1e-7)


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"window": 2}, "window must be >= 3"),
        ({"window": 3, "offset": "fit"}, "window must be >= 4"),
        ({"window": 5, "order": ArxOrder(2, 2, 1)}, "window must be >= 7"),
        ({"window": 1.5}, "window must be an integer"),
        ({"window": 10, "recompute_every": 0}, "recompute_every"),
    ],
)
def test_malsm_parameter_errors(kwargs: dict[str, object], fragment: str) -> None:
    u = square(100, 0.0, 1.0)
    with pytest.raises(InvalidParameterError, match=fragment):
        moving_window_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, **kwargs)  # type: ignore[arg-type]


def test_malsm_needs_one_window_of_data() -> None:
    u = square(50, 0.0, 1.0)
    with pytest.raises(InvalidDataError, match="too few samples: one window of 100"):
        moving_window_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, window=100)


# -- WLSM ----------------------------------------------------------------------------


# Random plants include taus under two sample periods, which are flagged (not checked here).
@pytest.mark.filterwarnings("ignore::thermolab.ident.IdentificationWarning")
@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    gamma=st.floats(0.6, 0.999),
    pmax=st.floats(1.0, 1e5),
    noise=st.sampled_from([0.0, 1e-3]),
    offset=st.sampled_from(["initial", "fit"]),
)
def test_paper_wlsm_equals_standard_rls_from_scaled_covariance(
    seed: int, gamma: float, pmax: float, noise: float, offset: str
) -> None:
    """Law: eqs. 13-15 with pmax are forgetting RLS started from P0 = (1 - γ)·pmax·I.

    The two differ only by rounding, which forgetting amplifies where the input
    does not excite every direction (P then grows as γ^-k): the input changes
    at least every 8 samples so that the comparison stays within 1e-7.
    """
    rng = np.random.default_rng(seed)
    u = exciting_input(rng, 400, max_hold=8)
    y = REFERENCE_MODEL.simulate(u) + 0.7 + noise * rng.standard_normal(400)
    w0 = [0.5, 0.01]
    paper = weighted_least_squares(u, y, 1.0, gamma, pmax, w0, offset=offset)
    standard = weighted_least_squares(
        u, y, 1.0, gamma, pmax, w0, form="standard", p0=(1 - gamma) * pmax, offset=offset
    )
    assert_array_equal(paper.reason_code, standard.reason_code)
    assert_allclose(paper.W, standard.W, rtol=1e-7, atol=1e-9)


def test_paper_form_refuses_gamma_one_and_says_why() -> None:
    u = square(50, 0.0, 1.0)
    y = REFERENCE_MODEL.simulate(u)
    with pytest.raises(InvalidParameterError, match="alpha = 1 - gamma = 0") as info:
        weighted_least_squares(u, y, 1.0, 1.0, 1e4, PAPER_W0)
    assert "form='standard'" in str(info.value)
    tr = weighted_least_squares(u, y, 1.0, 1.0, 1e4, PAPER_W0, form="standard")
    assert tr.valid[-1]


def test_standard_rls_without_forgetting_approaches_batch_least_squares() -> None:
    rng = np.random.default_rng(2)
    u = exciting_input(rng, 2000)
    y = REFERENCE_MODEL.simulate(u) + 1e-3 * rng.standard_normal(2000)
    rls = weighted_least_squares(u, y, 1.0, 1.0, 1e8, [0.0, 0.0], form="standard", offset="initial")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)  # coloured residuals: noise
        lsm = least_squares(u, y, 1.0, order=ArxOrder(), offset="initial")
    assert_allclose(rls.W[-1], lsm.W, rtol=1e-5)


@pytest.mark.parametrize(
    ("gamma", "pmax", "rows", "n_conv"),
    [(0.96, 1e4, "0-4", 200), (0.7, 1e4, "0-4", 60), (0.96, 1e3, "0-4", 250)],
)
def test_wlsm_converges_on_the_papers_square_wave(
    gamma: float, pmax: float, rows: str, n_conv: int
) -> None:
    u = square(2500, 0.0, 4.0)
    tr = weighted_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, gamma, pmax, PAPER_W0)
    assert tr.first_estimate == 0
    assert tr.valid.all()
    assert_allclose(tr.W[0], PAPER_W0)
    conv = tr.converged_at()
    assert conv["K"] is not None
    assert conv["K"] < n_conv
    assert conv["tau"] is not None
    assert conv["tau"] < n_conv
    assert f"{tr.K[-1]:.6f}" == "0.140090"
    assert f"{tr.tau[-1]:.6f}" == "250.126233"


def test_first_order_and_general_wlsm_kernels_are_identical() -> None:
    rng = np.random.default_rng(4)
    u = exciting_input(rng, 2000)
    y = REFERENCE_MODEL.simulate(u) + 1e-3 * rng.standard_normal(2000)
    n = u.size
    for paper in (True, False):
        results = []
        for first in (True, False):
            W = np.empty((n, 2), order="F")
            code = np.empty(n, dtype=np.int8)
            Wk = np.array(PAPER_W0)
            Pk = np.eye(2) * 400.0
            if first:
                _kernels_first_order.wlsm2_chunk(u, y, 1, n, paper, 0.96, Wk, Pk, W, code)
            else:
                _kernels.wlsm_chunk(u, y, 1, n, 1, 1, 0, False, paper, 0.96, Wk, Pk, W, code)
            results.append((W[1:], Pk))
        assert_array_equal(results[0][0], results[1][0])
        assert_array_equal(results[0][1], results[1][1])


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ambient=st.floats(-5, 5))
def test_wlsm_recovers_noise_free_parameters(seed: int, ambient: float) -> None:
    rng = np.random.default_rng(seed)
    u = exciting_input(rng, 1500, max_hold=8)
    y = simulate_first_order(u, 2.0, 15.0, 1.0, ambient=ambient)
    tr = weighted_least_squares(u, y, 1.0, 0.98, 1e4, [0.5, 0.5])
    assert_allclose([tr.K[-1], tr.tau[-1]], [2.0, 15.0], rtol=1e-6)


def test_wlsm_arx_order_and_fit_offset() -> None:
    rng = np.random.default_rng(9)
    u = exciting_input(rng, 3000, max_hold=10)
    a, b = (1.2, -0.35), (0.1, 0.05)
    y = simulate_arx(u, a, b, delay=1, ambient=-1.0)
    tr = weighted_least_squares(
        u, y, 1.0, 0.99, 1e4, None, order=ArxOrder(2, 2, 1), offset="fit", form="standard"
    )
    assert tr.param_names == ("a1", "a2", "b1", "b2", "c")
    assert_allclose(tr.W[-1, :4], [*a, *b], rtol=1e-6, atol=1e-9)
    assert_allclose(tr.W[-1, 4] / (1 - sum(a)), -1.0, rtol=1e-6)


def test_wlsm_overflow_is_flagged_from_there_on() -> None:
    u = np.full(50, 1.0)
    y = np.full(50, 1.0)
    y[20:] = 1e200  # finite data whose squares overflow
    tr = weighted_least_squares(u, y, 1.0, 0.9, 1e4, [0.5, 0.1], offset="none")
    assert tr.reason_code[19] != 6
    assert (tr.reason_code[21:] == 6).all()
    assert np.isnan(tr.W[21:]).all()
    assert "non-finite" in tr.invalid_reason[-1]


@pytest.mark.parametrize(
    ("args", "kwargs", "fragment"),
    [
        ((0.0, 1e4), {}, r"gamma \(forgetting factor\) must be in \(0, 1\)"),
        ((1.2, 1e4), {"form": "standard"}, r"must be in \(0, 1\]"),
        ((0.9, 0.0), {}, "pmax"),
        ((0.9, math.inf), {}, "pmax"),
        ((0.9, 1e4, [1.0]), {}, "w0 must have 2 entries"),
        ((0.9, 1e4, [1.0]), {"offset": "fit"}, "w0 must have 2 or 3 entries"),
        ((0.9, 1e4, [1.0, math.nan]), {}, "w0 must be finite"),
        ((0.9, 1e4), {"p0": 1.0}, "p0 is only for form='standard'"),
        ((0.9, 1e4), {"form": "standard", "p0": [[1.0, 2.0], [2.0, 1.0]]}, "positive definite"),
        ((0.9, 1e4), {"form": "standard", "p0": -1.0}, "p0"),
        ((0.9, 1e4), {"form": "standard", "p0": np.eye(3)}, "2x2"),
        ((0.9, 1e4), {"form": "kalman"}, "form must be one of"),
    ],
)
def test_wlsm_parameter_errors(
    args: tuple[object, ...], kwargs: dict[str, object], fragment: str
) -> None:
    u = square(50, 0.0, 1.0)
    with pytest.raises(InvalidParameterError, match=fragment):
        weighted_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, *args, **kwargs)  # type: ignore[arg-type]


def test_wlsm_explicit_covariance_matrix() -> None:
    u = square(500, 0.0, 4.0)
    y = REFERENCE_MODEL.simulate(u)
    scalar = weighted_least_squares(u, y, 1.0, 0.95, 1.0, PAPER_W0, form="standard", p0=50.0)
    matrix = weighted_least_squares(
        u, y, 1.0, 0.95, 1.0, PAPER_W0, form="standard", p0=np.eye(2) * 50.0
    )
    assert_array_equal(scalar.W, matrix.W)
    assert matrix.params["p0"] == [[50.0, 0.0], [0.0, 50.0]]
