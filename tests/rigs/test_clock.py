"""Clocks: virtual time advances instantly, scaled time runs X times a source."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.errors import InvalidParameterError
from thermolab.rigs.clock import Clock, RealClock, ScaledClock, VirtualClock, make_clock


def test_virtual_clock_jumps_to_the_target_and_never_goes_back() -> None:
    clock = VirtualClock(start=5.0)
    clock.sleep_until(7.5)
    assert clock.now() == 7.5
    clock.sleep_until(1.0)  # already past: no effect
    assert clock.now() == 7.5
    clock.advance(0.25)
    assert clock.now() == 7.75


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_virtual_clock_refuses_non_finite_instants(bad: float) -> None:
    clock = VirtualClock()
    with pytest.raises(InvalidParameterError, match="finite"):
        clock.sleep_until(bad)
    with pytest.raises(InvalidParameterError, match="finite"):
        VirtualClock(start=bad)


def test_virtual_clock_refuses_to_advance_backwards() -> None:
    with pytest.raises(InvalidParameterError, match=">= 0"):
        VirtualClock().advance(-1.0)


def test_scaled_clock_runs_speedup_times_its_source() -> None:
    source = VirtualClock(start=100.0)
    clock = ScaledClock(50.0, source=source, start=10.0)
    assert clock.now() == 10.0
    source.advance(2.0)
    assert clock.now() == pytest.approx(110.0)
    clock.sleep_until(1010.0)  # 900 virtual seconds = 18 source seconds
    assert source.now() == pytest.approx(120.0)
    assert clock.now() >= 1010.0


@settings(max_examples=50)
@given(
    speedup=st.floats(0.01, 1e4),
    start=st.floats(-1e6, 1e6),
    target=st.floats(-1e6, 1e7),
)
def test_scaled_clock_never_returns_before_the_target(
    speedup: float, start: float, target: float
) -> None:
    source = VirtualClock(start=12.345)
    clock = ScaledClock(speedup, source=source, start=start)
    clock.sleep_until(target)
    assert clock.now() >= target
    # ...and does not overshoot by more than rounding.
    assert clock.now() - max(target, start) <= 1e-6 * max(1.0, abs(target), abs(start))


@pytest.mark.parametrize("bad", [0.0, -2.0, math.nan, math.inf])
def test_scaled_clock_refuses_a_bad_speedup(bad: float) -> None:
    with pytest.raises(InvalidParameterError, match="speed-up"):
        ScaledClock(bad, source=VirtualClock())


def test_real_clock_returns_at_once_for_a_past_instant() -> None:
    clock = RealClock()
    t0 = clock.now()
    clock.sleep_until(t0 - 10.0)
    assert clock.now() >= t0


def test_make_clock_maps_speedups_to_clocks() -> None:
    assert isinstance(make_clock(None), RealClock)
    assert isinstance(make_clock(1.0), RealClock)
    assert isinstance(make_clock(math.inf), VirtualClock)
    scaled = make_clock(20.0)
    assert isinstance(scaled, ScaledClock)
    assert scaled.speedup == 20.0
    for clock in (RealClock(), VirtualClock(), scaled):
        assert isinstance(clock, Clock)
    with pytest.raises(InvalidParameterError, match="speed-up"):
        make_clock(-1.0)
