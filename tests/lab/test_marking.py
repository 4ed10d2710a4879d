"""The marking function (pure): laws that hold for every answer, and the no-mark rule."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.errors import InvalidParameterError
from thermolab.lab.assignments.grades import GradeRow, grades_csv, safe_cell
from thermolab.lab.assignments.marking import (
    MARK_MAX,
    Answers,
    Identified,
    Reference,
    Tolerances,
    assess,
    within,
)

gains = st.floats(min_value=1e-3, max_value=100.0)
taus = st.floats(min_value=0.5, max_value=5000.0)
thetas = st.floats(min_value=0.0, max_value=60.0)
rel = st.floats(min_value=0.01, max_value=0.5)
absolute = st.floats(min_value=0.5, max_value=30.0)


def _ident(ref: Reference, *, trusted: bool = True) -> Identified:
    warnings = () if trusted else ("the residuals are not white",)
    return Identified("lsm", ref.K, ref.tau, ref.theta, 97.0, trusted, warnings)


@settings(max_examples=200, deadline=None)
@given(gains, taus, thetas, rel, rel, absolute)
def test_answers_equal_to_the_reference_always_pass_with_full_marks(
    k: float, tau: float, theta: float, tk: float, tt: float, ta: float
) -> None:
    ref = Reference(k, tau, theta)
    tol = Tolerances(tk, tt, ta)
    result = assess(Answers(k, tau, theta), tol, ref, [_ident(ref)])
    assert result.state == "marked"
    assert result.mark == MARK_MAX
    assert all(c.verdict == "pass" for c in result.checks)
    assert len(result.checks) == 6  # three quantities, two bases


@settings(max_examples=200, deadline=None)
@given(gains, taus, rel, rel, st.floats(min_value=1.001, max_value=10.0), st.booleans())
def test_a_gain_outside_the_tolerance_always_fails_both_checks(
    k: float, tau: float, tk: float, tt: float, factor: float, above: bool
) -> None:
    ref = Reference(k, tau, 0.0)
    tol = Tolerances(tk, tt)
    off = 1 + tk * factor if above else 1 - min(tk * factor, 0.999) * 1.0
    answer = k * off
    if math.isclose(answer, k, rel_tol=tk * 1.0000001):
        return  # the lower side clipped inside the tolerance: nothing to say
    result = assess(Answers(answer, tau), tol, ref, [_ident(ref)])
    gain = [c for c in result.checks if c.quantity == "K"]
    assert [c.verdict for c in gain] == ["fail", "fail"]
    assert result.mark is not None
    assert result.mark < MARK_MAX
    assert "more than" in gain[0].why


@settings(max_examples=100, deadline=None)
@given(gains, taus, thetas, st.floats(min_value=-0.99, max_value=0.99))
def test_within_is_symmetric_in_the_tolerance_band(
    k: float, tau: float, theta: float, frac: float
) -> None:
    tol = Tolerances(0.1, 0.1, 5.0)
    assert within(k * (1 + 0.1 * frac), k, "K", tol)
    assert within(theta + 5.0 * frac, theta, "theta", tol)
    assert not within(k * (1 + 0.1 * (1.01 + abs(frac))), k, "K", tol)


@settings(max_examples=100, deadline=None)
@given(gains, taus, thetas)
def test_an_untrusted_identification_never_gives_a_mark(k: float, tau: float, th: float) -> None:
    ref = Reference(k, tau, th)
    result = assess(Answers(k, tau, th), Tolerances(theta=5.0), ref, [_ident(ref, trusted=False)])
    assert result.mark is None
    assert result.state == "review"
    assert any("not trustworthy" in n and "residuals are not white" in n for n in result.notes)
    assert all(c.verdict == "not_judged" for c in result.checks if c.basis == "run")


def test_one_trusted_method_is_enough_and_the_answer_may_match_any_of_them() -> None:
    ref = Reference(0.14, 250.0, 0.0)
    lsm = Identified("lsm", 0.20, 300.0, 0.0, 80.0, True)
    oe = Identified("oe", 0.14, 250.0, 0.0, 99.0, True)
    bad = Identified("srm", 0.14, 250.0, 0.0, None, False, ("short record",))
    result = assess(Answers(0.14, 250.0), Tolerances(), ref, [lsm, oe, bad])
    assert result.mark == MARK_MAX
    assert {c.method for c in result.checks if c.basis == "run"} == {"oe"}
    assert any("srm" in n for n in result.notes)  # the untrusted one is still explained


def test_a_rig_without_reference_is_marked_on_the_run_alone() -> None:
    run = Identified("lsm", 0.6, 140.0, 16.0, 95.0, True)
    result = assess(Answers(0.6, 200.0, 16.0), Tolerances(theta=5.0), None, [run])
    assert [c.basis for c in result.checks] == ["run", "run", "run"]
    assert result.mark == pytest.approx(MARK_MAX * 2 / 3, abs=0.05)
    tau = next(c for c in result.checks if c.quantity == "tau")
    assert tau.verdict == "fail"
    assert "42.9 % off" in tau.why


def test_a_missing_theta_fails_when_theta_is_asked() -> None:
    ref = Reference(0.6, 140.0, 16.0)
    result = assess(Answers(0.6, 140.0), Tolerances(theta=5.0), ref, [_ident(ref)])
    theta = [c for c in result.checks if c.quantity == "theta"]
    assert [c.verdict for c in theta] == ["fail", "fail"]
    assert theta[0].why == "no answer was given"


@pytest.mark.parametrize(
    "kwargs", [{"K": 0.0}, {"tau": 1.5}, {"K": math.nan}, {"theta": -1.0}, {"theta": math.inf}]
)
def test_tolerances_out_of_range_are_refused(kwargs: dict[str, float]) -> None:
    with pytest.raises(InvalidParameterError, match="tolerance"):
        Tolerances(**kwargs)


@given(st.text(max_size=30))
def test_no_text_cell_starts_like_a_formula(text: str) -> None:
    assert not safe_cell(text).startswith(("=", "+", "-", "@", "\t", "\r"))


def test_the_grades_csv_keeps_a_hostile_name_as_text() -> None:
    row = GradeRow("c", 1, "+SUM(A1)", "ana", "@cmd", "missing", None, 10.0, None, None, True, None)
    line = grades_csv([row]).splitlines()[1]
    assert line == "c,1,'+SUM(A1),ana,'@cmd,missing,,10.0,yes,,,,,,,,,"
    # A teacher's comment on an overridden mark is text too.
    commented = replace(row, state="marked", mark=9.0, automatic_mark=6.5, comment="=1+1 ok")
    line = grades_csv([commented]).splitlines()[1]
    assert line.endswith(",6.5,'=1+1 ok")
