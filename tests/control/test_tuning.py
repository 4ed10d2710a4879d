"""Tuning rules against values worked by hand from the published formulas."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest
from numpy.testing import assert_allclose

from thermolab.control import FOPDT, PIDGains, as_fopdt, tune
from thermolab.errors import InvalidParameterError

# The model of Seborg et al.'s worked examples: K = 1, tau = 10 s, theta = 2 s (theta/tau = 0.2).
MODEL = (1.0, 10.0, 2.0)


@pytest.mark.parametrize(
    ("rule", "form", "tau_c", "expected"),
    [
        # Ziegler-Nichols: PI Kc = 0.9 tau/(K theta), Ti = theta/0.3;
        # PID Kc = 1.2 tau/(K theta), Ti = 2 theta, Td = theta/2
        ("zn", "pi", None, (4.5, 6.666666666667, 0.0)),
        ("zn", "pid", None, (6.0, 4.0, 1.0)),
        # Cohen-Coon PI: Kc = 5 (0.9 + 0.2/12), Ti = 2 (30 + 0.6) / (9 + 4)
        ("cc", "pi", None, (4.583333333333, 4.707692307692, 0.0)),
        # Cohen-Coon PID: Kc = 5 (4/3 + 0.05), Ti = 2 (32 + 1.2) / (13 + 1.6), Td = 8 / 11.4
        ("cc", "pid", None, (6.916666666667, 4.547945205479, 0.701754385965)),
        # SIMC: Kc = tau / (K (tau_c + theta)) = 10/4, Ti = min(10, 4 * 4) = 10
        ("simc", "pi", 2.0, (2.5, 10.0, 0.0)),
        # SIMC with a slow loop: Ti = min(10, 4 (0.5 + 2)) = 10; fast: tau_c = 0.1 -> Ti = 8.4
        ("simc", "pi", 0.1, (10 / 2.1, 8.4, 0.0)),
        # IMC PI: Kc = tau / (K (lambda + theta)) = 10/5, Ti = tau
        ("imc", "pi", 3.0, (2.0, 10.0, 0.0)),
        # IMC PID: Kc = (tau + theta/2)/(K(lambda + theta/2)) = 11/4, Ti = 11, Td = 20/22
        ("imc", "pid", 3.0, (2.75, 11.0, 0.909090909091)),
    ],
)
def test_rules_match_hand_worked_values(
    rule: str, form: str, tau_c: float | None, expected: tuple[float, float, float]
) -> None:
    t = tune(MODEL, rule, form=form, tau_c=tau_c)
    assert_allclose((t.Kp, t.Ti, t.Td), expected, rtol=1e-10, atol=1e-12)
    assert t.form == form


def test_gain_scales_inversely_with_the_plant_gain_and_keeps_its_sign() -> None:
    for rule in ("imc", "simc", "zn", "cc"):
        base = tune(MODEL, rule)
        negative = tune((-4.0, 10.0, 2.0), rule)
        assert_allclose(negative.Kp, -base.Kp / 4, rtol=1e-12)
        assert_allclose((negative.Ti, negative.Td), (base.Ti, base.Td), rtol=1e-12)


def test_default_speed_is_the_dead_time() -> None:
    assert tune(MODEL, "simc").tau_c == 2.0
    assert tune((1.0, 10.0), "simc").tau_c == 1.0  # no dead time: tau / 10


@dataclass
class Estimate:
    K: float
    tau: float
    valid: bool = True


def test_models_from_objects_with_or_without_theta() -> None:
    assert as_fopdt(Estimate(0.14, 250.0)) == FOPDT(0.14, 250.0, 0.0)
    assert as_fopdt(FOPDT(1, 2, 3)) == FOPDT(1, 2, 3)
    with pytest.raises(InvalidParameterError, match="invalid model"):
        as_fopdt(Estimate(0.14, 250.0, valid=False))


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: tune(MODEL, "magic"), "unknown tuning rule"),
        (lambda: tune(MODEL, "simc", form="pid"), "defines the form"),
        (lambda: tune((1.0, 10.0), "zn"), "needs a dead time"),
        (lambda: tune(MODEL, "cc", tau_c=3.0), "no closed-loop speed"),
        (lambda: tune(MODEL, "imc", tau_c=-1.0), "tau_c must be"),
        (lambda: tune((0.0, 10.0, 1.0), "imc"), "gain K"),
        (lambda: tune((1.0, math.nan, 1.0), "imc"), "tau"),
        (lambda: tune((1.0, 10.0, 1.0, 4.0), "imc"), "is \\(K, tau\\)"),
        (lambda: PIDGains(1.0, 0.0), "ti must be finite"),
        (lambda: PIDGains(math.inf, 1.0), "kp must be finite"),
        (lambda: PIDGains(1.0, 1.0, -1.0), "td must be finite"),
    ],
)
def test_bad_input_is_refused_clearly(call: object, match: str) -> None:
    with pytest.raises(InvalidParameterError, match=match):
        call()  # type: ignore[operator]
