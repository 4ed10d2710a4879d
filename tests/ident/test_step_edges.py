"""SRM on short and edge records: a result or a domain error, never a crash.

A result shown to a student must be right or say plainly why not: on any
record, :func:`step_response` either refuses it with the documented domain
error (no step, no response, too few samples after the step) or returns a
result, and that result is ``trusted`` only when its first-order response
follows the record.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.errors import InsufficientExcitationError, InvalidDataError
from thermolab.ident import IdentificationWarning, StepResponseResult, step_response
from thermolab.ident.advice import ADVICE, warning_kind


def _quiet(t: np.ndarray, u: np.ndarray, y: np.ndarray) -> StepResponseResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        return step_response(t, u, y, min_samples=0)


def _follows(r: StepResponseResult) -> bool:
    """The identified first-order response follows the record after the step."""
    tr = r.t[r.step_index :] - r.step_time
    elapsed = np.maximum(tr - r.theta, 0.0)
    model = r.baseline + (r.final_value - r.baseline) * -np.expm1(-elapsed / r.tau)
    # Scaled by the record's largest value: squares of readings near 1e300 overflow.
    scale = max(float(np.max(np.abs(r.y))), 1e-300)
    miss = scale * float(np.sqrt(np.mean(((r.y[r.step_index :] - model) / scale) ** 2)))
    spread = scale * float(np.std(np.diff(r.y / scale)))
    return miss <= 0.11 * abs(r.final_value - r.baseline) + 4.0 * spread


def test_ended_step_run_whose_polish_overflowed() -> None:
    # The regression: an ENDed step run, 12 samples, the step one sample in, huge
    # readings. The tail fit's polish stepped tau to exp(-710) and raised
    # OverflowError out of the method (and out of the run's END).
    t = np.arange(12.0)
    u = np.where(t >= 1, 10.0, 0.0)
    y = np.where(t >= 2, 1e160, 0.0)
    r = _quiet(t, u, y)
    assert not r.trusted
    assert r.to_dict()["trusted"] is False
    # A jump one sample after the step: tau under a sample period, which the samples
    # cannot show (the other methods' plausibility check).
    assert [warning_kind(w) for w in r.warnings] == ["implausible time constant"]


def test_a_response_already_past_63_percent_at_the_step_has_no_time_constant() -> None:
    # The output rose before the step and stays: every sample after the step is past
    # 63.2 % of the change, tau came out 0 and the method divided by it
    # (ZeroDivisionError).
    t = np.arange(17.0)
    u = np.where(t >= 10, 10.0, 0.0)
    y = np.minimum(t, 10.0)
    r = _quiet(t, u, y)
    assert not r.trusted
    assert r.warnings[0].startswith("no sound fit: the 7 samples after the step give K = 0.5")
    assert r.to_dict()["time_constants_recorded"] is None
    json.dumps(r.to_dict(), allow_nan=False)


def test_huge_readings_are_not_an_overflow() -> None:
    t = np.arange(17.0)
    u = np.where(t >= 11, 10.0, 0.0)
    r = _quiet(t, u, np.linspace(0.0, 1e300, 17))
    assert not r.trusted
    assert "poor fit" in [warning_kind(w) for w in r.warnings]


def test_a_record_ended_right_after_the_step_says_why() -> None:
    t = np.arange(8.0)
    u = np.where(t >= 7, 10.0, 0.0)
    with pytest.raises(InvalidDataError, match="only 1 samples follow"):
        step_response(t, u, np.zeros(8))


def test_a_clean_short_record_is_trusted() -> None:
    t = np.arange(40.0)
    u = np.where(t >= 2, 10.0, 0.0)
    y = 0.5 * -np.expm1(-np.maximum(t - 2, 0.0) / 5.0)
    r = _quiet(t, u, y)
    assert r.trusted, r.warnings
    assert math.isclose(r.tau, 5.0, rel_tol=1e-6)


_SCALES = st.sampled_from([1e-300, 1e-9, 1.0, 1e6, 1e150, 1e300])


@st.composite
def _records(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = draw(st.integers(2, 40))
    ks = draw(st.integers(0, n - 1))  # the step anywhere, the last sample included
    t = np.arange(float(n)) * draw(st.sampled_from([1e-3, 1.0, 1e3]))
    u = np.where(np.arange(n) >= ks, draw(st.sampled_from([-10.0, 1e-6, 10.0, 1e300])), 0.0)
    if ks == 0:
        u[:] = u[0]  # the step before the record: the method says "no step"
    kind = draw(st.sampled_from(["flat", "exponential", "noise", "jump", "values"]))
    scale = draw(_SCALES)
    k = np.arange(n)
    if kind == "flat":
        y = np.full(n, scale)
    elif kind == "exponential":
        tau = draw(st.floats(0.01, 100.0))
        y = scale * -np.expm1(-np.maximum(k - ks, 0) / tau)
    elif kind == "noise":
        y = scale * np.random.default_rng(draw(st.integers(0, 2**32 - 1))).standard_normal(n)
    elif kind == "jump":
        y = np.where(k > ks, scale, 0.0)
    else:
        y = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=n, max_size=n))) * scale
    return t, u, y


@settings(max_examples=400, deadline=None)
@given(_records())
def test_any_short_record_gives_a_result_or_a_domain_error(
    record: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    try:
        r = _quiet(*record)
    except (InvalidDataError, InsufficientExcitationError):
        return  # the documented refusals (no step, no response, too few samples after it)
    d = r.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["trusted"] is r.trusted
    if r.trusted:
        assert math.isfinite(r.K)
        assert r.K != 0.0
        assert math.isfinite(r.tau)
        assert r.tau > 0.0
        assert _follows(r)
    else:
        # Why not is said plainly: a warning, or no figures at all.
        assert r.warnings or not (math.isfinite(r.K) and math.isfinite(r.tau))


def test_the_new_warnings_have_advice() -> None:
    assert {"no sound fit", "poor fit"} <= ADVICE.keys()
