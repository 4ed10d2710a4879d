"""A rate-changeable clock (a lab twin's): time stays continuous across changes of rate."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.errors import InvalidParameterError
from thermolab.rigs.clock import Clock, RateClock, VirtualClock


def test_a_rate_clock_is_a_clock_that_runs_rate_times_its_source() -> None:
    source = VirtualClock(start=100.0)
    clock = RateClock(50.0, source=source, start=10.0)
    assert isinstance(clock, Clock)
    assert clock.now() == 10.0
    source.advance(2.0)
    assert clock.now() == pytest.approx(110.0)
    clock.sleep_until(1010.0)  # 900 virtual seconds = 18 source seconds
    assert source.now() == pytest.approx(120.0)
    assert clock.now() >= 1010.0


def test_a_change_of_rate_keeps_the_time_and_changes_the_pace() -> None:
    source = VirtualClock()
    clock = RateClock(10.0, source=source)
    source.advance(3.0)
    before = clock.now()
    clock.set_rate(200.0)
    assert clock.now() == before == pytest.approx(30.0)
    assert clock.rate == 200.0
    source.advance(0.5)
    assert clock.now() == pytest.approx(130.0)
    clock.set_rate(1.0)
    source.advance(4.0)
    assert clock.now() == pytest.approx(134.0)


class _HookedSource(VirtualClock):
    """A virtual source that calls ``hook`` on its first sleep (another thread's change)."""

    def __init__(self, hook: Callable[[], None]) -> None:
        super().__init__()
        self._hook: Callable[[], None] | None = hook
        self.sleeps: list[float] = []

    def sleep_until(self, t: float) -> None:
        super().sleep_until(t)
        self.sleeps.append(t)
        hook, self._hook = self._hook, None
        if hook is not None:
            hook()


def test_a_sleep_in_progress_honours_a_new_rate_after_its_slice() -> None:
    clock: RateClock
    source = _HookedSource(lambda: clock.set_rate(100.0))
    clock = RateClock(10.0, source=source, max_slice=1.0)
    # 1000 virtual seconds: 100 source seconds at 10x; the rate becomes 100x after
    # the first 1 s slice (10 virtual s), so the other 990 take 9.9 source seconds.
    clock.sleep_until(1000.0)
    assert source.sleeps[0] == 1.0
    assert source.now() == pytest.approx(10.9)
    assert clock.now() >= 1000.0
    assert clock.now() == pytest.approx(1000.0)


@pytest.mark.parametrize("bad", [0.0, -2.0, math.nan, math.inf])
def test_a_rate_clock_refuses_a_bad_rate(bad: float) -> None:
    with pytest.raises(InvalidParameterError, match="positive finite"):
        RateClock(bad)
    clock = RateClock(2.0, source=VirtualClock())
    with pytest.raises(InvalidParameterError, match="positive finite"):
        clock.set_rate(bad)
    assert clock.rate == 2.0


def test_a_rate_clock_refuses_a_non_finite_instant() -> None:
    with pytest.raises(InvalidParameterError, match="finite"):
        RateClock(2.0, source=VirtualClock()).sleep_until(math.nan)


_STEP = st.one_of(
    st.tuples(st.just("advance"), st.floats(0.0, 1e3)),
    st.tuples(st.just("rate"), st.floats(1e-3, 1e4)),
    st.tuples(st.just("sleep"), st.floats(-1e3, 1e5)),  # virtual seconds from now
)


@settings(max_examples=200, deadline=None)
@given(
    rate=st.floats(1e-3, 1e4),
    start=st.floats(-1e6, 1e6),
    steps=st.lists(_STEP, max_size=30),
)
def test_any_sequence_of_rate_changes_keeps_the_time_continuous_and_never_decreasing(
    rate: float, start: float, steps: list[tuple[str, float]]
) -> None:
    source = VirtualClock(start=7.0)
    # Slices long enough that a sleep on a virtual source takes few of them.
    clock = RateClock(rate, source=source, start=start, max_slice=1e6)
    last = clock.now()
    assert last == start
    for kind, value in steps:
        if kind == "advance":
            pace = clock.rate
            source.advance(value)
            now = clock.now()
            # Advances at the rate in force (relative to the size of the numbers).
            scale = max(abs(last), pace * value, 1.0)
            assert now - last == pytest.approx(pace * value, abs=1e-9 * scale)
        elif kind == "rate":
            clock.set_rate(value)
            now = clock.now()
            assert now == last  # no jump: the same source instant reads the same
        else:
            clock.sleep_until(last + value)
            now = clock.now()
            assert now >= last + value
        assert now >= last
        last = now
