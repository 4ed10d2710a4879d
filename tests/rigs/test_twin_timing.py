"""The twin's timing: exact at any speed-up, and an exact transport delay.

A twin advances by exactly ``dt`` per sample whatever the wall clock does: the
runner passes each sample's scheduled instant to ``read``/``apply``, and the
twin evaluates its physics there. Late or irregular wake-ups of the clock
change nothing in the record; only a preset's own (seeded) jitter does.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from thermolab.errors import InvalidParameterError
from thermolab.rigs import ScaledClock, TwinRig, VirtualClock
from thermolab.rigs.clock import Clock
from thermolab.runner import Experiment, RunResult
from thermolab.signals import automatic_square, parse_signal
from thermolab.simulation import REFERENCE_MODEL, simulate_arx, simulate_first_order


class _LateSource:
    """A source clock that wakes late, irregularly: a loaded machine, seeded.

    Every ``sleep_until`` overshoots by a random 0-15 ms, and one wake-up in
    twenty by 60 ms more (at a speed-up of 100 that is up to 7.5 s of virtual
    time, several sample periods).
    """

    def __init__(self, seed: int) -> None:
        self._clock = VirtualClock()
        self._rng = np.random.default_rng(seed)

    def now(self) -> float:
        return self._clock.now()

    def sleep_until(self, t: float) -> None:
        late = self._rng.uniform(0.0, 0.015) + (0.06 if self._rng.random() < 0.05 else 0.0)
        self._clock.sleep_until(t + late)


def _run(rig: TwinRig, samples: int, signal: str = "") -> RunResult:
    source = automatic_square(4.0, 6.0, 1.0) if not signal else parse_signal(signal, (0, 100))
    return Experiment(rig, 1.0, samples, signal=source, interlocks=None).run()


def test_a_twin_at_a_speedup_on_a_late_clock_gives_the_exact_simulation() -> None:
    clock: Clock = ScaledClock(100.0, source=_LateSource(seed=5))
    with TwinRig("paper", clock=clock) as rig:
        result = _run(rig, 2000)
    assert result.late > 500  # the clock really was late, often by several periods
    assert result.missed > 0
    assert_array_equal(result.u, automatic_square(4.0, 6.0, 1.0).sample(np.arange(2000.0)))
    expected = simulate_first_order(result.u, K=REFERENCE_MODEL.K, tau=REFERENCE_MODEL.tau, dt=1.0)
    assert_allclose(result.y, expected, rtol=0, atol=1e-13)
    assert_array_equal(result.jitter, 0.0)  # the record shows no jitter the twin did not simulate


@pytest.mark.parametrize("preset", ["paper-practical", "tclab"])
def test_late_wake_ups_change_nothing_in_a_seeded_realistic_twin(preset: str) -> None:
    signal = "square:4:6:0.01" if preset == "paper-practical" else "square:0:80:0.002"
    with TwinRig(preset, clock=VirtualClock(), seed=11) as rig:
        on_time = _run(rig, 1500, signal)
    late_clock = ScaledClock(100.0, source=_LateSource(seed=6))
    with TwinRig(preset, clock=late_clock, seed=11) as rig:
        late = _run(rig, 1500, signal)
    assert late.late > 300
    # Noise, quantisation, the preset's own jitter and the tclab dead time: bit for bit.
    assert_array_equal(late.y, on_time.y)
    assert_array_equal(late.t_read, on_time.t_read)


def test_read_and_apply_at_an_instant_ignore_the_clock() -> None:
    clock = VirtualClock()
    with TwinRig("paper", clock=clock) as rig:
        rig.power_on()
        clock.sleep_until(900.0)  # far ahead of the instants asked for
        rig.apply(10.0, at=0.0)
        reading = rig.read(at=REFERENCE_MODEL.tau)
    assert reading.t == REFERENCE_MODEL.tau
    assert_allclose(reading.value, 10 * REFERENCE_MODEL.K * (1 - np.exp(-1.0)), rtol=1e-13)


@pytest.mark.parametrize("at", [float("nan"), float("inf"), "soon"])
def test_a_sample_instant_must_be_a_finite_time(at: object) -> None:
    with TwinRig("paper", clock=VirtualClock()) as rig:
        rig.power_on()
        with pytest.raises(InvalidParameterError, match="sample instant must be a finite"):
            rig.read(at=at)  # type: ignore[arg-type]
        with pytest.raises(InvalidParameterError, match="sample instant must be a finite"):
            rig.apply(1.0, at=at)  # type: ignore[arg-type]


def test_a_dead_time_of_whole_samples_is_the_arx_delay() -> None:
    # Inputs act 5 s after they are applied: y[k+1] = a y[k] + b u[k-5].
    n = 800
    u = np.where((np.arange(n) // 40) % 2 == 0, 8.0, 2.0)
    clock = VirtualClock()
    y = np.empty(n)
    with TwinRig("paper", clock=clock, dead_time=5.0) as rig:
        rig.power_on()
        for k in range(n):
            y[k] = rig.read(at=float(k)).value
            rig.apply(float(u[k]), at=float(k))
    m = REFERENCE_MODEL
    assert_allclose(y, simulate_arx(u, [m.a], [m.b], delay=5), rtol=0, atol=1e-13)


@settings(max_examples=40, deadline=None)
@given(
    theta=st.floats(0.01, 60.0),
    steps=st.lists(st.tuples(st.floats(0.05, 80.0), st.floats(0.0, 10.0)), min_size=1, max_size=15),
)
def test_a_delayed_twin_is_the_plain_twin_shifted_by_the_dead_time(
    theta: float, steps: list[tuple[float, float]]
) -> None:
    plain = TwinRig("paper", clock=VirtualClock())
    delayed = TwinRig("paper", clock=VirtualClock(), dead_time=theta)
    plain.power_on()
    delayed.power_on()
    t = 0.0
    for hold, u in steps:
        plain.apply(u, at=t)
        delayed.apply(u, at=t)
        for s in np.linspace(t, t + hold, 4):
            assert_allclose(
                delayed.read(at=float(s) + theta).value,
                plain.read(at=float(s)).value,
                rtol=1e-12,
                atol=1e-14,
            )
        t += hold


def test_power_off_travels_through_the_dead_time_too() -> None:
    clock = VirtualClock()
    with TwinRig("paper", clock=clock, dead_time=10.0) as rig:
        rig.power_on()
        rig.apply(10.0)
        clock.sleep_until(100.0)
        rig.power_off()
        assert rig.applied_input == 0.0
        warm = rig.read().value
        clock.sleep_until(109.0)
        assert rig.read().value > warm  # the lamp's heat is still on its way
        clock.sleep_until(111.0)
        peak = rig.true_output(110.0)
        assert rig.read().value < peak


def test_dead_time_must_not_be_negative() -> None:
    with pytest.raises(InvalidParameterError, match="dead_time must be a finite number >= 0"):
        TwinRig("paper", dead_time=-1.0)


def test_late_samples_exist_only_when_simulated_seeded_and_disclosed() -> None:
    late_options = {"late_probability": 0.2, "late_mean": 0.3}
    with TwinRig("paper", clock=VirtualClock(), seed=4, **late_options) as rig:  # type: ignore[arg-type]
        on_time = _run(rig, 3000)
    with TwinRig(
        "paper",
        clock=ScaledClock(100.0, source=_LateSource(seed=9)),
        seed=4,
        **late_options,  # type: ignore[arg-type]
    ) as rig:
        busy = _run(rig, 3000)
    assert_array_equal(busy.t_read, on_time.t_read)  # seeded: the wall clock plays no part
    assert_array_equal(busy.y, on_time.y)
    late = on_time.jitter[on_time.jitter > 0]
    assert 0.17 < late.size / 3000 < 0.23
    assert_allclose(late.mean(), 0.3, rtol=0.15)
    # Reading and input of a late sample both happen at the late instant.
    reference = TwinRig("paper", clock=VirtualClock())
    reference.power_on()
    y = np.empty(3000)
    for k, instant in enumerate(on_time.t_read):
        y[k] = reference.read(at=float(instant)).value
        reference.apply(float(on_time.u[k]), at=float(instant))
    assert_allclose(on_time.y, y, rtol=0, atol=1e-14)


def test_late_probability_must_be_a_probability() -> None:
    with pytest.raises(InvalidParameterError, match=r"late_probability must be a probability"):
        TwinRig("paper", late_probability=1.5)
