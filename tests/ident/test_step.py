"""SRM: the step response method."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from thermolab.errors import InsufficientExcitationError, InvalidDataError, InvalidParameterError
from thermolab.ident import IdentificationWarning, StepResponseResult, step_response
from thermolab.signals import Square, Step
from thermolab.simulation import REFERENCE_MODEL, simulate_first_order

K_REF, TAU_REF = REFERENCE_MODEL.K, REFERENCE_MODEL.tau


def _paper_record(n: int = 2000, at: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(float(n))
    u = Step(0.0, 10.0, at=at).sample(t)
    return t, u, REFERENCE_MODEL.simulate(u)


def _quiet(*args: object, **kwargs: object) -> StepResponseResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        return step_response(*args, **kwargs)  # type: ignore[arg-type]


# --- Table I -----------------------------------------------------------------------------


def test_table1_srm_row_reproduced() -> None:
    # 2000 samples t = 0..1999 s, 0 V at the first sample, 10 V from t = 1 s.
    r = step_response(*_paper_record())
    assert round(r.K_last_sample, 6) == 0.140042
    assert round(r.K_last_sample - K_REF, 6) == -48e-6
    assert_allclose(r.K, K_REF, rtol=1e-10)
    assert round(r.tau, 6) == 250.126233
    assert_allclose(r.tau, TAU_REF, rtol=1e-11)
    assert r.step_index == 1
    assert r.step_time == 1.0
    assert (r.u_before, r.u_after, r.amplitude) == (0.0, 10.0, 10.0)
    assert r.baseline == 0.0
    assert r.final_value_basis == "extrapolated"
    assert r.tau_basis == "63.2% crossing"
    assert r.settled
    assert r.warnings == ()
    assert_allclose(r.t63, 1.0 + TAU_REF, rtol=1e-12)


@pytest.mark.parametrize(
    ("n", "at", "m", "printed"),
    [
        (2000, 1.0, 1998, 0.140042),  # the convention that rounds to the paper's figure
        (2000, 0.0, 1999, 0.140043),
        (2001, 0.0, 2000, 0.140043),  # v0(2000)/10: 0.1400428, the paper's figure truncated
    ],
)
def test_last_sample_gain_is_m_steps_of_input(n: int, at: float, m: int, printed: float) -> None:
    t, u, y = _paper_record(n, at)
    r = step_response(t, u, y, u_initial=0.0 if at == 0.0 else None)
    assert_allclose(r.K_last_sample, K_REF * -math.expm1(-m / TAU_REF), rtol=1e-12)
    assert round(r.K_last_sample, 6) == printed
    assert_allclose([r.K, r.tau], [K_REF, TAU_REF], rtol=1e-10)


def test_ts_needs_the_settled_change() -> None:
    # The 63.2 % point of the last-sample change is 0.15 s early: the paper's Ts is not it.
    t, u, y = _paper_record()
    r = step_response(t, u, y)
    level = r.baseline + (1 - math.exp(-1)) * (r.last_value - r.baseline)
    j = int(np.argmax(y >= level))
    t_last = t[j - 1] + (level - y[j - 1]) / (y[j] - y[j - 1])
    assert t_last - r.step_time < 250.0
    assert abs(r.tau - TAU_REF) < 1e-6


# --- laws --------------------------------------------------------------------------------


@settings(max_examples=30, deadline=None)
@given(
    K=st.floats(0.01, 5.0) | st.floats(-5.0, -0.01),
    tau_samples=st.floats(5.0, 200.0),
    dt=st.sampled_from([0.1, 0.5, 1.0, 2.0]),
    u0=st.floats(-10, 10),
    du=st.floats(1.0, 10.0),
    cooling=st.booleans(),
    ambient=st.floats(-3, 3),
    k_step=st.integers(1, 50),
)
def test_exact_first_order_record_recovers_k_and_tau(
    K: float,
    tau_samples: float,
    dt: float,
    u0: float,
    du: float,
    cooling: bool,
    ambient: float,
    k_step: int,
) -> None:
    tau = tau_samples * dt
    u1 = u0 - du if cooling else u0 + du
    u1 = float(np.clip(u1, -10, 10))
    if abs(u1 - u0) < 1.0:
        u1 = u0 + (1.0 if u0 < 0 else -1.0)
    n = k_step + math.ceil(8 * tau_samples)
    t = np.arange(n) * dt
    u = np.where(np.arange(n) >= k_step, u1, u0)
    y = simulate_first_order(u, K, tau, dt, y0=ambient + K * u0, ambient=ambient)
    r = step_response(t, u, y, min_samples=0)
    assert_allclose(r.K, K, rtol=1e-8)
    assert_allclose(r.tau, tau, rtol=1e-8)
    assert r.direction == ("heating" if u1 > u0 else "cooling")
    assert r.step_index == k_step
    assert_allclose(r.baseline, ambient + K * u0, rtol=1e-12, atol=1e-12)
    assert r.settled
    assert r.warnings == ()


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), jitter=st.floats(0.0, 0.3))
def test_jittered_sample_times_are_still_exact(seed: int, jitter: float) -> None:
    # The crossing interpolation is exact for an exponential wherever the samples fall.
    rng = np.random.default_rng(seed)
    t = np.arange(1500.0) + rng.uniform(-jitter, jitter, 1500)
    t[0] = 0.0
    k_step = 20
    ts = t[k_step]
    u = np.where(np.arange(t.size) >= k_step, 7.0, 2.0)
    y = 1.5 + 0.2 * u[0] + np.where(t >= ts, 0.2 * 5.0 * -np.expm1(-(t - ts) / 180.0), 0.0)
    r = step_response(t, u, y, min_samples=0)
    assert_allclose([r.K, r.tau], [0.2, 180.0], rtol=1e-8)


def test_noise_settled_gain_beats_last_sample() -> None:
    rng = np.random.default_rng(2024)
    t, u, y = _paper_record(2100, at=100.0)
    errors_fit, errors_last, taus = [], [], []
    for _ in range(20):
        r = step_response(t, u, y + rng.normal(0.0, 0.005, y.size))
        errors_fit.append(r.K - K_REF)
        errors_last.append(r.K_last_sample - K_REF)
        taus.append(r.tau)
    # The tail fit averages the noise that the single last sample carries.
    assert np.std(errors_fit) < 0.7 * np.std(errors_last)
    assert abs(np.mean(errors_fit)) < 3e-4
    assert_allclose(np.mean(taus), TAU_REF, rtol=2e-3)


def test_noisy_crossing_is_not_the_first_one() -> None:
    # With noise the first crossing of the level comes early; the line fit does not.
    rng = np.random.default_rng(5)
    t, u, y = _paper_record(2100, at=100.0)
    taus = [step_response(t, u, y + rng.normal(0, 0.02, y.size)).tau for _ in range(20)]
    assert abs(np.mean(taus) - TAU_REF) < 2.5


# --- warnings ----------------------------------------------------------------------------


def test_unsettled_record_warns_and_extrapolates() -> None:
    t, u, y = _paper_record(600)
    with pytest.warns(IdentificationWarning, match="not settled") as record:
        r = step_response(t, u, y, min_samples=0)
    assert len(record) == 1
    assert not r.settled
    assert_allclose(r.time_constants_recorded, 598.0 / TAU_REF, rtol=1e-9)
    assert_allclose([r.K, r.tau], [K_REF, TAU_REF], rtol=1e-9)
    assert r.K_last_sample < 0.92 * K_REF
    assert r.warnings[0].startswith("not settled: the record lasts 2.39 time constants")
    assert "record at least 1001 samples after the step" in r.warnings[0]


def test_short_record_warns() -> None:
    t, u, y = _paper_record(1500)
    with pytest.warns(IdentificationWarning, match="short record: 1500 samples") as record:
        r = step_response(t, u, y)
    assert [w.split(":")[0] for w in r.warnings] == ["short record"]
    assert len(record) == 1


def test_small_step_warns() -> None:
    t = np.arange(2500.0)
    u = np.where(t >= 10, 4.5, 4.0)
    y = REFERENCE_MODEL.simulate(u, y0=4.0 * K_REF)
    with pytest.warns(IdentificationWarning, match=r"small step: the input changes by 0.5 V"):
        r = step_response(t, u, y)
    assert_allclose([r.K, r.tau], [K_REF, TAU_REF], rtol=1e-8)
    assert step_response(t, u, y, min_step=0.5).warnings == ()


def test_moving_before_the_step_warns() -> None:
    t = np.arange(2600.0)
    u = np.where(t >= 300, 10.0, 0.0)
    y = REFERENCE_MODEL.simulate(u, y0=0.5)  # still cooling from 0.5 V when the step comes
    with pytest.warns(IdentificationWarning, match="moving before the step"):
        step_response(t, u, y)


def test_record_ending_before_the_crossing_uses_the_fit() -> None:
    t, u, y = _paper_record(200)
    r = _quiet(t, u, y, min_samples=0)
    assert r.tau_basis == "tail fit"
    assert math.isnan(r.t63)
    assert_allclose([r.K, r.tau], [K_REF, TAU_REF], rtol=1e-6)
    assert any(w.startswith("no 63.2% crossing") for w in r.warnings)
    assert any(w.startswith("not settled") for w in r.warnings)


def test_every_warning_is_also_emitted() -> None:
    t = np.arange(200.0)
    u = np.where(t >= 1, 0.5, 0.0)
    y = REFERENCE_MODEL.simulate(u)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = step_response(t, u, y)
    assert [str(w.message) for w in caught] == list(r.warnings)
    assert all(w.category is IdentificationWarning for w in caught)
    assert issubclass(IdentificationWarning, UserWarning)
    assert len(r.warnings) == 4


# --- steps found in the record -----------------------------------------------------------


def test_step_at_the_first_sample_needs_u_initial() -> None:
    t = np.arange(2000.0)
    u = np.full(t.size, 10.0)
    y = REFERENCE_MODEL.simulate(u)
    with pytest.raises(InsufficientExcitationError, match="give u_initial"):
        step_response(t, u, y)
    r = step_response(t, u, y, u_initial=0.0)
    assert (r.step_index, r.step_time, r.amplitude) == (0, 0.0, 10.0)
    assert_allclose([r.K, r.tau], [K_REF, TAU_REF], rtol=1e-10)


def test_cooling_step_from_an_operating_point() -> None:
    t = np.arange(3000.0)
    u = np.where(t >= 500, -6.0, 4.0)  # lamp at 4 V, then the fan at 6 V
    ambient = 2.2
    y = REFERENCE_MODEL.simulate(u, y0=ambient + 4.0 * K_REF, ambient=ambient)
    r = step_response(t, u, y)
    assert r.direction == "cooling"
    assert r.amplitude == -10.0
    assert_allclose(r.baseline, ambient + 4.0 * K_REF, rtol=1e-12)
    assert_allclose(r.final_value, ambient - 6.0 * K_REF, rtol=1e-9)
    assert_allclose([r.K, r.tau], [K_REF, TAU_REF], rtol=1e-9)


def test_input_noise_below_a_tenth_of_the_step_is_tolerated() -> None:
    rng = np.random.default_rng(3)
    t, u, y = _paper_record(2500, at=50.0)
    u_measured = u + rng.normal(0.0, 0.05, u.size)
    r = step_response(t, u_measured, y)
    assert r.step_index == 50
    assert_allclose(r.amplitude, 10.0, atol=0.02)
    assert_allclose(r.tau, TAU_REF, rtol=1e-9)


# --- errors ------------------------------------------------------------------------------


def test_no_step_is_an_error() -> None:
    t = np.arange(100.0)
    with pytest.raises(InsufficientExcitationError, match="no step: the input stays at 3 V"):
        step_response(t, np.full(100, 3.0), np.zeros(100))


def test_several_steps_are_an_error() -> None:
    t = np.arange(100.0)
    u = Square(4.0, 6.0, 0.1).sample(t)
    with pytest.raises(InvalidDataError, match="the input changes more than once"):
        step_response(t, u, REFERENCE_MODEL.simulate(u))


def test_output_that_does_not_respond_is_an_error() -> None:
    t = np.arange(500.0)
    u = np.where(t >= 10, 10.0, 0.0)
    y = 1.0 + np.random.default_rng(0).normal(0, 0.01, t.size)
    with pytest.raises(InsufficientExcitationError, match="does not respond to the step"):
        step_response(t, u, y)


def test_too_few_samples_after_the_step() -> None:
    t = np.arange(10.0)
    u = np.where(t >= 6, 10.0, 0.0)
    with pytest.raises(InvalidDataError, match="only 4 samples follow"):
        step_response(t, u, REFERENCE_MODEL.simulate(u))


@pytest.mark.parametrize(
    ("t", "u", "y", "error", "match"),
    [
        ([0, 1, 2], [0, 1], [0, 1, 2], InvalidDataError, "same number of samples"),
        ([0, 1, 2], [0, 1, 1], [0, 1, 2, 3], InvalidDataError, "same number of samples"),
        ([0, 1, 1], [0, 1, 1], [0, 1, 2], InvalidDataError, "strictly increasing"),
        ([0, 1, 2], [0, math.nan, 1], [0, 1, 2], InvalidDataError, r"u\[1\]"),
        ([0, 1], [0, 1, 2], [0, 1, 2], InvalidDataError, "one time per sample"),
    ],
)
def test_bad_records(
    t: list[float], u: list[float], y: list[float], error: type, match: str
) -> None:
    with pytest.raises(error, match=match):
        step_response(t, u, y)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"min_step": -1.0}, "min_step must be a finite number of volts >= 0"),
        ({"min_samples": -1}, "min_samples must be >= 0"),
        ({"min_samples": 2.5}, "min_samples must be an integer"),
        ({"settle_time_constants": 0.0}, "settle_time_constants must be a finite number > 0"),
        ({"u_initial": math.inf}, "u_initial must be finite"),
    ],
)
def test_bad_options(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(InvalidParameterError, match=match):
        step_response(*_paper_record(), **kwargs)


# --- output ------------------------------------------------------------------------------


def test_to_dict_is_json() -> None:
    t, u, y = _paper_record(200)
    d = _quiet(t, u, y).to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert d["method"] == "srm"
    assert d["t63"] is None
    assert d["tau_basis"] == "tail fit"
    assert isinstance(d["warnings"], list)
    assert "t" not in d
    full = _quiet(t, u, y).to_dict(arrays=True)
    assert full["y"] == y.tolist()


def test_model_and_equality() -> None:
    r = step_response(*_paper_record())
    assert_allclose([r.model.K, r.model.tau], [r.K, r.tau], rtol=0)
    assert r == step_response(*_paper_record())


def test_plot(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    fig = step_response(*_paper_record()).plot()
    assert len(fig.axes) == 2
    out = tmp_path / "srm.png"
    fig.savefig(out)
    assert out.stat().st_size > 1000
