"""The predicted closed loop and the step metrics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from thermolab.control import (
    PID,
    PIDGains,
    predict_closed_loop,
    predict_record_step,
    rest_warning,
    settling_warning,
    step_metrics,
    to_control,
    tune,
)
from thermolab.errors import InvalidDataError, InvalidParameterError


def test_open_loop_part_matches_the_exact_fopdt_step() -> None:
    # A tiny Kp with a huge Ti is nearly open loop: u stays at Kp * r... instead, check the
    # plant through a saturated controller: u = u_max from the step on.
    K, tau, theta, dt = 2.0, 10.0, 2.5, 1.0
    resp = predict_closed_loop(
        (K, tau, theta), PIDGains(1e4, 1e6), dt=dt, samples=60, setpoint=1e6,
        u_limits=(0.0, 1.0),
    )  # fmt: skip
    assert_allclose(resp.u, 1.0)
    t = resp.t
    exact = np.where(t > theta, K * (1 - np.exp(-(t - theta) / tau)), 0.0)
    assert_allclose(resp.y, exact, atol=1e-12)


def test_the_loop_settles_on_the_set_point_with_integral_action() -> None:
    model = (0.6, 140.0, 15.9)
    gains = tune(model, "simc").gains
    resp = predict_closed_loop(
        model, gains, dt=1.0, samples=1500, setpoint=50.0, step_at=10.0, y0=21.0,
        u0=0.0, u_limits=(0.0, 100.0),
    )  # fmt: skip
    assert abs(resp.y[-1] - 50.0) < 0.01
    m = resp.metrics
    assert m.step_time == 10.0
    assert m.step == pytest.approx(29.0)
    assert 0.0 <= m.overshoot < 10.0  # SIMC with tau_c = theta: little overshoot
    assert 50.0 < m.settling_time < 400.0
    assert m.iae > 0


def test_faster_rules_overshoot_more() -> None:
    model = (1.0, 10.0, 2.0)
    over = {
        rule: predict_closed_loop(
            model, tune(model, rule).gains, dt=0.05, samples=2000, setpoint=1.0
        ).metrics.overshoot
        for rule in ("simc", "zn")
    }
    assert over["zn"] > over["simc"] + 10.0


def test_metrics_of_a_record_that_never_settles() -> None:
    t = np.arange(5.0)
    m = step_metrics(t, [0, 1, 1, 1, 1], [0, 0, 0.5, 0.7, 0.8])
    assert math.isnan(m.settling_time)
    assert m.to_dict()["settling_time"] is None
    with pytest.raises(InvalidDataError, match="no set-point step"):
        step_metrics(t, [1.0] * 5, [1.0] * 5)
    with pytest.raises(InvalidDataError, match="same length"):
        step_metrics(t, [1.0] * 4, [1.0] * 5)


@settings(max_examples=60, deadline=None)
@given(
    kp=st.floats(0.01, 100.0),
    ti=st.floats(0.1, 1000.0),
    td=st.floats(0.0, 100.0),
    ys=st.lists(st.floats(-100.0, 100.0), min_size=1, max_size=40),
)
# Found by Hypothesis: sqrt(Ti * Td) of a subnormal Td is 0, a zero tracking time.
@example(kp=1.0, ti=0.1, td=5e-324, ys=[0.0])
def test_the_output_never_leaves_its_limits(
    kp: float, ti: float, td: float, ys: list[float]
) -> None:
    pid = PID(PIDGains(kp, ti, td), 0.0, 100.0)
    for y in ys:
        u = pid.update(20.0, y, 1.0)
        assert 0.0 <= u <= 100.0


def test_back_calculation_limits_windup() -> None:
    gains = PIDGains(5.0, 20.0)
    limited = PID(gains, 0.0, 100.0)
    for _ in range(500):
        limited.update(80.0, 20.0, 1.0)  # far below the set point, saturated
    # Without anti-windup the integral would be 5/20 * 60 * 500 = 7500.
    assert limited.integral < 2 * 100.0
    # Reaching the set point, the output leaves saturation at once.
    assert limited.update(80.0, 80.0, 1.0) < 100.0


def test_bumpless_gain_change_and_tracking() -> None:
    pid = PID(PIDGains(2.0, 50.0, 5.0), 0.0, 100.0)
    pid.track(37.0, 40.0, 35.0)
    assert pid.update(40.0, 35.0, 1.0) == pytest.approx(37.0, abs=1e-12)
    before = pid.update(40.0, 35.0, 1.0)
    pid.set_gains(PIDGains(4.0, 50.0, 5.0), 40.0, 35.0)
    after = pid.update(40.0, 35.0, 1.0)
    # Only one more integral step apart (at the new gain), no proportional jump of 2 * 5.
    assert abs(after - before) < 4.0 * 5.0 / 50.0 + 1e-9


def test_to_control_closed_loop_agrees_with_the_model() -> None:
    G = to_control((2.0, 10.0, 3.0), pade_order=3)
    assert G.dcgain() == pytest.approx(2.0)
    assert len(G.den[0][0]) == 5  # first-order lag times a third-order Padé
    with pytest.raises(InvalidParameterError, match="pade_order"):
        to_control((2.0, 10.0, 3.0), pade_order=0)


def test_a_record_moving_at_its_step_is_flagged_not_at_rest() -> None:
    model = (0.6, 140.0, 15.9)
    gains = tune(model, "simc").gains
    run = predict_closed_loop(
        model, gains, dt=1.0, samples=900, setpoint=45.0, y0=21.0, u_limits=(0.0, 100.0)
    )
    measured, predicted = predict_record_step(
        model, gains, run.t, run.r, run.y, run.u, dt=1.0, u_rest=0.0, u_limits=(0.0, 100.0)
    )
    # The record is the prediction itself: the same figures, and it started at rest.
    assert measured == predicted.metrics
    assert rest_warning(model, measured, run.t, run.y) is None
    # A box 15 degC above its rest output, cooling with the model's time constant.
    warm = run.y + 15.0 * np.exp(-run.t / 140.0)
    r = np.full_like(run.t, 45.0)
    moved = rest_warning(model, step_metrics(run.t, r, warm), run.t, warm)
    assert moved is not None
    away = float(moved.split("the box was about ")[1].split(" from rest")[0])
    assert 13.0 < away < 16.0  # the slope's tangent over the dead time: 15 e^(-t/tau)
    assert "does not describe this run" in moved
    # No dead time: nothing to look through.
    assert rest_warning((0.6, 140.0), step_metrics(run.t, r, warm), run.t, warm) is None


def test_settling_times_either_side_of_the_band_are_said_not_comparable() -> None:
    # The kit's twin, tuned (SIMC PI) from two LSM fits of its noisy step: dead times
    # of 16 s (the usual one) and 18 s (a noise realisation that CI met).
    twin = (0.6, 140.0, 15.9)
    figures = {}
    for fit in ((0.6, 138.5, 16.0), (0.593, 137.3, 18.0)):
        gains = tune(fit, "simc", form="pi").gains
        run = predict_closed_loop(
            twin, gains, dt=1.0, samples=900, setpoint=45.0, y0=21.0, u_limits=(0.0, 100.0)
        )
        measured, predicted = predict_record_step(
            fit, gains, run.t, run.r, run.y, run.u, dt=1.0, u_rest=0.0, u_limits=(0.0, 100.0)
        )
        figures[fit[2]] = (measured, predicted.metrics)
    usual, edge = figures[16.0], figures[18.0]
    # Peaks well beyond the band: the settling times agree, nothing to say.
    assert abs(usual[0].settling_time - usual[1].settling_time) < 0.05 * usual[0].settling_time
    assert settling_warning(*usual) is None
    # A measured peak inside the 2 % band, a predicted one outside: the settling times
    # are 25 % apart, the IAEs within 5 % -- and the warning says which to compare.
    measured, predicted = edge
    assert measured.overshoot < 2.0 < predicted.overshoot
    assert abs(measured.settling_time - predicted.settling_time) > 0.25 * measured.settling_time
    assert abs(measured.iae - predicted.iae) < 0.05 * measured.iae
    note = settling_warning(measured, predicted)
    assert note is not None
    assert "(1.0 % measured, 2.3 % predicted)" in note
    assert "compare the overshoot and the IAE" in note
