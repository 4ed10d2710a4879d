"""Physics and realism of the digital twin."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.optimize import curve_fit

from thermolab.errors import InvalidParameterError, RigFaultError, RigTimeoutError
from thermolab.rigs.base import RigState
from thermolab.rigs.clock import VirtualClock
from thermolab.rigs.twin import DAQ16_STEP, PRESETS, TwinParams, TwinRig, twin_preset
from thermolab.simulation import REFERENCE_MODEL, simulate_first_order

KS, TS = 0.140090, 250.126233


def _twin(preset: str = "paper", **kwargs: object) -> tuple[TwinRig, VirtualClock]:
    clock = VirtualClock()
    rig = TwinRig(preset, clock=clock, **kwargs)  # type: ignore[arg-type]
    rig.power_on()
    return rig, clock


def test_paper_preset_is_the_reference_model() -> None:
    p = twin_preset("paper")
    assert (p.gain, p.time_constant) == (REFERENCE_MODEL.K, REFERENCE_MODEL.tau)
    assert p.noise_std == 0
    assert p.jitter_std == 0
    assert p.quant_step is None


def test_step_response_is_the_analytic_exponential_at_any_instant() -> None:
    rig, clock = _twin()
    rig.apply(10.0)
    instants = np.sort(np.random.default_rng(3).uniform(0.0, 3000.0, 200))
    values = []
    for t in instants:
        clock.sleep_until(float(t))
        values.append(rig.read().value)
    assert_allclose(values, 10 * KS * (1 - np.exp(-instants / TS)), rtol=1e-13, atol=1e-15)


def test_sampled_every_second_it_is_eq4() -> None:
    # A 4<->6 V square wave at 0.1 Hz, read then applied each second, as a runner does.
    n = 600
    u = np.where((np.arange(n) // 5) % 2 == 0, 6.0, 4.0)
    rig, clock = _twin()
    y = np.empty(n)
    for k in range(n):
        clock.sleep_until(float(k))
        y[k] = rig.read().value
        rig.apply(float(u[k]))
    expected = simulate_first_order(u, K=KS, tau=TS, dt=1.0)
    assert_allclose(y, expected, rtol=0, atol=1e-14)


@settings(max_examples=40)
@given(
    steps=st.lists(
        st.tuples(st.floats(0.0, 500.0), st.floats(-10.0, 10.0)), min_size=1, max_size=20
    )
)
def test_piecewise_constant_input_is_integrated_exactly(steps: list[tuple[float, float]]) -> None:
    # Independent reference: the one-node heat balance solved segment by segment.
    rig, clock = _twin()
    y = 0.0
    for dt, u in steps:
        rig.apply(u)
        lam = (1 + 0.1 * max(-u, 0.0)) / TS
        target = KS * max(u, 0.0) / (1 + 0.1 * max(-u, 0.0))
        y = target + (y - target) * math.exp(-lam * dt)
        clock.advance(dt)
    assert_allclose(rig.read().value, y, rtol=1e-12, atol=1e-14)


def test_two_node_model_matches_the_matrix_exponential() -> None:
    rig, clock = _twin("tclab", realism=False, dead_time=0.0)
    p = rig.params
    assert p.sensor_lag is not None
    A = np.array([[-1 / p.time_constant, 0], [1 / p.sensor_lag, -1 / p.sensor_lag]])
    B = np.array([p.gain / p.time_constant, 0.0])
    x = np.zeros(2)
    rng = np.random.default_rng(7)
    for _ in range(30):
        u, dt = float(rng.uniform(0, 100)), float(rng.uniform(0.1, 120))
        rig.apply(u)
        clock.advance(dt)
        Ad = scipy.linalg.expm(A * dt)
        x = Ad @ x + np.linalg.solve(A, (Ad - np.eye(2)) @ B) * u
        assert_allclose(rig.read().value, p.ambient + x[1], rtol=1e-12)


def test_tclab_twin_step_fits_the_kit_figures() -> None:
    rig, _clock = _twin("tclab", realism=False)
    rig.apply(50.0)
    t = np.arange(0.0, 1200.0)
    y = np.array([rig.true_output(float(s)) for s in t]) - 21.0

    def fopdt(t: np.ndarray, K: float, tau: float, theta: float) -> np.ndarray:
        return np.where(t > theta, 50 * K * (1 - np.exp(-(t - theta) / tau)), 0.0)

    (K, tau, theta), _ = curve_fit(fopdt, t, y, p0=[0.5, 100.0, 10.0])
    assert_allclose([K, tau, theta], [0.6, 140.0, 16.0], rtol=0.05)
    assert rig.params.dead_time == 13.0  # most of θ is pure delay, as on the kit
    assert abs(y[13]) < 1e-12  # nothing reaches the sensor before the delay has passed
    assert y[14] > 1e-6


def test_the_fan_cools_faster_but_never_below_ambient() -> None:
    rig, clock = _twin("paper", ambient=2.5)
    rig.apply(-10.0)
    clock.advance(5000.0)
    assert rig.read().value == pytest.approx(2.5, abs=1e-15)  # at ambient: a fan does nothing
    rig.apply(10.0)
    clock.advance(1000.0)
    warm = rig.read().value - 2.5
    rig.apply(0.0)
    clock.advance(100.0)
    natural = rig.read().value - 2.5
    # The same warm start, cooled by the fan at full speed instead.
    rig2, clock2 = _twin("paper", ambient=2.5, initial_output=2.5 + warm)
    rig2.apply(-10.0)
    clock2.advance(100.0)
    fanned = rig2.read().value - 2.5
    assert_allclose(natural, warm * math.exp(-100 / TS), rtol=1e-12)
    assert_allclose(fanned, warm * math.exp(-100 * 2 / TS), rtol=1e-12)  # c = 0.1/V at 10 V
    assert fanned > 0.0


def test_seeded_realism_is_repeatable_and_seeds_differ() -> None:
    def record(seed: int) -> list[float]:
        rig, clock = _twin("paper-practical", seed=seed)
        out = []
        for k in range(300):
            clock.sleep_until(float(k))
            out.append(rig.read().value)
            rig.apply(10.0 if k >= 10 else 0.0)
        return out

    assert record(11) == record(11)
    assert record(11) != record(12)


def test_switching_one_noise_source_off_leaves_the_others_draws_alone() -> None:
    def noise(**kw: object) -> np.ndarray:
        rig, clock = _twin("paper", seed=5, **kw)
        out = []
        for k in range(50):
            clock.sleep_until(float(k))
            out.append(rig.read().value)
        return np.array(out)

    white = noise(noise_std=0.01)
    both = noise(noise_std=0.01, jitter_std=0.1)
    assert_allclose(both, white, atol=1e-15)  # jitter at equilibrium changes nothing


def test_white_noise_statistics() -> None:
    rig, clock = _twin("paper", noise_std=0.02, seed=1)
    values = []
    for k in range(20000):
        clock.sleep_until(float(k))
        values.append(rig.read().value)
    v = np.array(values)
    assert abs(v.mean()) < 4 * 0.02 / math.sqrt(v.size)
    assert_allclose(v.std(), 0.02, rtol=0.03)
    lag1 = np.corrcoef(v[:-1], v[1:])[0, 1]
    assert abs(lag1) < 0.03


def test_colored_noise_has_its_correlation_time() -> None:
    rig, clock = _twin("paper", colored_noise_std=0.01, colored_noise_time=10.0, seed=2)
    values = []
    for k in range(40000):
        clock.sleep_until(float(k))
        values.append(rig.read().value)
    v = np.array(values)
    assert_allclose(v.std(), 0.01, rtol=0.1)
    lag1 = np.corrcoef(v[:-1], v[1:])[0, 1]
    assert_allclose(lag1, math.exp(-1 / 10.0), atol=0.02)


def test_quantisation_puts_readings_on_the_16_bit_grid() -> None:
    rig, clock = _twin("paper", quant_step=DAQ16_STEP, quant_origin=-10.0)
    rig.apply(10.0)
    readings = []
    for k in range(1500, 2000):  # late in the step: less than one code per second
        clock.sleep_until(float(k))
        exact = rig.true_output()
        value = rig.read().value
        assert abs(value - exact) <= DAQ16_STEP / 2 + 1e-15
        readings.append(value)
    codes = (np.array(readings) + 10.0) / DAQ16_STEP
    assert_allclose(codes, np.round(codes), atol=1e-9)
    steps = np.diff(np.unique(readings))
    assert_allclose(steps.min(), DAQ16_STEP, rtol=1e-9)


def test_the_adc_range_clips_readings() -> None:
    rig, clock = _twin("paper", gain=2.0, output_limit=None, adc_range=(-10.0, 10.0 - DAQ16_STEP))
    rig.apply(10.0)
    clock.advance(5000.0)
    assert rig.read().value == 10.0 - DAQ16_STEP


def test_tclab_quantisation_is_the_kits() -> None:
    rig, _clock = _twin("tclab", seed=3)
    values = {round(rig.read().value, 9) for _ in range(50)}
    codes = [(v + 50.0) / 0.3223 for v in values]
    assert_allclose(codes, np.round(codes), atol=1e-6)


def test_jitter_samples_at_an_undisclosed_instant() -> None:
    rig, clock = _twin("paper", jitter_std=0.05, seed=4)
    rig.apply(10.0)
    offsets = []
    for k in range(1, 2001):
        clock.sleep_until(float(k))
        reading = rig.read()
        assert reading.t == float(k)  # the host sees the requested instant
        slope = 10 * KS / TS * math.exp(-k / TS)
        offsets.append((reading.value - rig.true_output()) / slope)
    offsets_arr = np.array(offsets)
    assert_allclose(offsets_arr.std(), 0.05, rtol=0.1)
    assert abs(offsets_arr.mean()) < 0.01


def test_ambient_drift_reaches_the_box_through_its_lag() -> None:
    period, amplitude = 600.0, 0.1
    rig, clock = _twin("paper", drift_amplitude=amplitude, drift_period=period, seed=6)
    clock.advance(10 * TS)  # let the start-up transient die out
    values = []
    for _k in range(int(period)):
        clock.advance(1.0)
        values.append(rig.read().value)
    swing = (max(values) - min(values)) / 2
    omega = 2 * math.pi / period
    assert_allclose(swing, amplitude / math.sqrt(1 + (omega * TS) ** 2), rtol=1e-3)


def test_saturation_applies_the_bound_and_reports_it() -> None:
    rig, _clock = _twin("paper", saturation=(-5.0, 8.0))
    assert rig.apply(10.0) == 8.0
    assert rig.applied_input == 8.0
    assert rig.apply(-7.0) == -5.0
    assert rig.apply(3.0) == 3.0


def test_power_off_and_close_put_the_lamp_off() -> None:
    rig, _clock = _twin()
    rig.apply(10.0)
    rig.power_off()
    assert rig.applied_input == 0.0
    rig.power_on()
    rig.apply(5.0)
    rig.close()
    assert rig.applied_input == 0.0


def test_the_output_limit_cuts_the_lamp() -> None:
    rig, clock = _twin("paper", output_limit=1.0)
    rig.apply(10.0)
    clock.advance(1000.0)
    with pytest.raises(RigFaultError, match="exceeds the limit"):
        rig.read()
    assert rig.applied_input == 0.0
    assert rig.state is RigState.FAULTED


@pytest.mark.parametrize("timeout", [False, True])
def test_an_injected_fault_fires_at_its_instant(timeout: bool) -> None:
    rig, clock = _twin()
    rig.apply(10.0)
    rig.inject_fault("lamp relay stuck", at=100.0, timeout=timeout)
    clock.advance(99.0)
    rig.read()
    clock.advance(1.0)
    expected = RigTimeoutError if timeout else RigFaultError
    with pytest.raises(expected, match="lamp relay stuck") as info:
        rig.read()
    assert type(info.value) is expected
    assert rig.fault() is not None
    assert rig.applied_input == 0.0
    rig.clear_fault()
    rig.power_on()
    rig.apply(1.0)


def test_an_injected_fault_can_fire_on_apply() -> None:
    rig, _ = _twin()
    rig.inject_fault()
    with pytest.raises(RigFaultError, match="injected fault"):
        rig.apply(1.0)
    assert rig.state is RigState.FAULTED


def test_realism_false_switches_everything_off() -> None:
    rig, clock = _twin("paper-practical", realism=False, seed=1)
    clock.advance(10.0)
    assert rig.read().value == 2.5


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ({"time_constant": 0.0}, "time_constant"),
        ({"noise_std": -1.0}, "noise_std"),
        ({"saturation": (5.0, 1.0)}, "saturation"),
        ({"safe_input": 20.0}, "safe_input"),
        ({"sensor_lag": 250.126233}, "differ"),
        ({"colour": 1}, "unknown twin option"),
    ],
)
def test_invalid_parameters_are_refused_with_the_reason(
    override: dict[str, object], message: str
) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        TwinRig("paper", clock=VirtualClock(), **override)  # type: ignore[arg-type]


def test_unknown_preset_lists_the_known_ones() -> None:
    with pytest.raises(InvalidParameterError, match="paper, paper-practical, tclab"):
        twin_preset("lab")


def test_presets_round_trip_through_dict() -> None:
    for params in PRESETS.values():
        data = params.to_dict()
        for key in ("adc_range", "saturation"):
            if data[key] is not None:
                data[key] = tuple(data[key])
        assert TwinParams(**data) == params


@pytest.mark.parametrize("leave", ["power_off", "fault", "close"])
def test_every_way_to_rest_puts_the_fan_back_at_its_declared_default(leave: str) -> None:
    # Issue #23: a closed loop's fan left at 50 % changed every later run's plant
    # (Ks 0.112 instead of 0.140). Resting is the declaration's state, fan included.
    from thermolab.rigs import RigSpec

    rig, clock = _twin("paper", realism=False)
    rig.set_fan(50.0)
    rig.apply(10.0)
    clock.advance(10.0)
    if leave == "fault":
        rig.inject_fault("over-temperature")
        with pytest.raises(RigFaultError):
            rig.read()
    else:
        getattr(rig, leave)()
    fan = RigSpec.parse("sim").fan
    assert fan is not None
    assert rig.fan == fan.default == 0.0
    assert rig.applied_input == rig.describe().safe_input
