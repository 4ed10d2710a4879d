"""The verdict on a whole-record model (issue #21): checks that hold on real kits."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from thermolab.ident.oe import (
    output_error,
    output_error_at_rest,
    simulate_fopdt,
    simulate_fopdt_at,
)
from thermolab.ident.verdict import MIN_FIT, free_run_fit, judge


def kit(seed: int, t: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A TCLab-like FOPDT step (0.6 °C/%, 140 s, 15 s) with 0.05 °C of noise."""
    t = np.arange(700.0) if t is None else t
    u = np.where(t >= 20.0, 50.0, 0.0)
    rng = np.random.default_rng(seed)
    y = 21.0 + simulate_fopdt_at(t, u, 0.6, 140.0, 15.0) + rng.normal(0, 0.05, t.size)
    return t, u, y


@settings(max_examples=25, deadline=None, derandomize=True)
@given(st.floats(0.1, 2.0), st.floats(5.0, 300.0), st.floats(0.0, 30.0), st.integers(0, 2**31 - 1))
def test_at_the_time_stamps_agrees_with_the_sampled_model_on_a_regular_axis(
    K: float, tau: float, theta: float, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(0, 100, 12), 25)
    x_at = simulate_fopdt_at(np.arange(u.size, dtype=float), u, K, tau, theta)
    assert_allclose(x_at, simulate_fopdt(u, K, tau, theta, 1.0), rtol=0, atol=1e-9 * K * 100)


def test_at_the_time_stamps_is_exact_on_an_irregular_axis() -> None:
    t = np.array([0.0, 0.7, 2.9, 3.0, 9.4, 20.0])
    u = np.array([0.0, 10.0, 10.0, 0.0, 0.0, 0.0])
    x = simulate_fopdt_at(t, u, 0.5, 4.0, 1.0)

    def step(s: np.ndarray, at: float) -> np.ndarray:
        return -np.expm1(-np.maximum(s - at, 0.0) / 4.0)

    expect = 5.0 * (step(t, 1.7) - step(t, 4.0))
    assert_allclose(x, expect, rtol=0, atol=1e-12)


def test_a_right_model_fits_free_run_and_predicts_the_last_third() -> None:
    t, u, y = kit(1)
    record, last = free_run_fit(t, u, y, 0.6, 140.0, 15.0)
    assert record > 99.0
    assert last > 99.0
    slow, slow_last = free_run_fit(t, u, y, 0.6, 400.0, 15.0)
    assert slow < record
    assert slow_last < last


def test_the_residual_tests_and_the_sample_count_do_not_decide() -> None:
    t, u, y = kit(2)
    v = judge(
        0.6, 140.0, 15.0,
        ["residual test failed: the residuals are not white", "short record: 700 samples"],
        t, u, y,
    )  # fmt: skip
    assert v.trusted
    assert len(v.notes) == 2
    assert v.reasons == ()


@pytest.mark.parametrize(
    ("K", "tau", "theta", "words"),
    [
        (0.6, 180.0, 15.0, "disagrees with oe"),
        (0.6, 140.0, 5.0, "dead time uncertain"),
        (0.3, 140.0, 15.0, "disagrees with oe"),
    ],
)
def test_a_model_that_disagrees_with_the_output_error_fit_is_not_trusted(
    K: float, tau: float, theta: float, words: str
) -> None:
    t, u, y = kit(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        oe = output_error(u, y, 1.0, t=t)
    peer = {"method": "oe", "K": oe.K, "tau": oe.tau, "theta": oe.theta}
    assert judge(0.6, 140.0, 15.0, [], t, u, y, peer=peer).trusted
    v = judge(K, tau, theta, [], t, u, y, peer=peer)
    assert not v.trusted
    assert any(words in r for r in v.reasons)


def test_no_model_no_convergence_and_timing_say_why() -> None:
    t, u, y = kit(
        4, np.cumsum(np.r_[0.0, np.full(699, 1.0)]) + np.r_[np.zeros(400), np.full(300, 30.0)]
    )
    gap = ["gap in time: 1 gap (first after t = 399 s)"]
    assert not judge(None, None, None, [], t, u, y, reason="not excited").trusted
    assert (
        "no model: not excited"
        in judge(None, None, None, [], t, u, y, reason="not excited").reasons[0]
    )
    assert "did not converge" in judge(0.6, 140.0, 15.0, [], t, u, y, converged=False).reasons[0]
    assert not judge(0.6, 140.0, 15.0, gap, t, u, y).trusted
    assert judge(0.6, 140.0, 15.0, gap, t, u, y, honours_time=True).trusted


def test_a_model_that_does_not_follow_the_record_is_not_trusted() -> None:
    t, u, y = kit(5)
    v = judge(0.6, 10.0, 0.0, [], t, u, y)
    assert not v.trusted
    assert v.fit_record is not None
    assert v.fit_record < MIN_FIT


def test_a_model_that_depends_on_what_came_before_the_record_is_not_trusted() -> None:
    t, u, y = kit(6)
    same = {"K": 0.61, "tau": 143.0, "u0": 50.0}
    other = {"K": 0.3, "tau": 143.0, "u0": 50.0}
    assert judge(0.6, 140.0, 15.0, [], t, u, y, at_rest=same).trusted
    v = judge(0.6, 140.0, 15.0, [], t, u, y, at_rest=other)
    assert not v.trusted
    assert v.reasons[0].startswith("start uncertain: the input is on (50) from the first row")


def test_output_error_can_take_the_kit_at_rest_before_the_record() -> None:
    t = np.arange(-1.0, 700.0)
    u = np.where(t >= 0.0, 50.0, 0.0)
    y = 21.0 + simulate_fopdt_at(t, u, 0.6, 140.0, 15.0)
    y = y + np.random.default_rng(7).normal(0, 0.05, t.size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = output_error_at_rest(u, y, 1.0, t=t)
    assert_allclose([r.K, r.tau, r.theta], [0.6, 140.0, 15.0], rtol=0.02, atol=0.5)


def test_assess_speaks_the_records_units_in_every_word_it_gives() -> None:
    from thermolab.errors import InvalidDataError
    from thermolab.ident.assess import assess

    t, u, y = kit(3)
    u = np.where(t >= 20.0, 0.5, 0.0)  # a small step: the warning names the input twice
    y = 21.0 + simulate_fopdt_at(t, u, 0.6, 140.0, 15.0)
    plain = assess("srm", t, u, y, 1.0)
    assert any(" V" in w for w in plain.summary["warnings"])  # the methods speak of volts
    said = assess("srm", t, u, y, 1.0, units=("%", "°C"))
    words = [*said.summary["warnings"], *said.verdict.reasons, *said.verdict.notes]
    assert words
    assert not [w for w in words if " V" in w]
    (small,) = [w for w in said.summary["warnings"] if w.startswith("small step")]
    assert "by 0.5 %, under 1 %" in small
    assert small.endswith("a step of at least 1 %")
    # The verdict is judged on the kinds, not the words: the same either way.
    assert said.trusted == plain.trusted
    # A refusal too, as the same type of error.
    with pytest.raises(InvalidDataError, match="too few samples"):
        assess("srm", t[:5], u[:5], y[:5], 1.0, units=("%", "°C"))


def test_a_whole_record_model_that_is_right_is_trusted_and_says_so() -> None:
    from thermolab.ident.assess import assess

    t, u, y = kit(4)
    for method in ("srm", "lsm", "oe"):
        a = assess(method, t, u, y, 1.0, units=("%", "°C"))
        assert a.trusted, (method, a.verdict.reasons)
        assert_allclose([a.summary["K"], a.summary["tau"]], [0.6, 140.0], rtol=0.1)
