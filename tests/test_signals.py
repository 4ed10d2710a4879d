"""Excitation signals: values, edges, clipping, the text syntax and its errors."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from thermolab.errors import InvalidParameterError, SignalSpecError
from thermolab.signals import (
    PRBS,
    SIGNAL_SYNTAX,
    Constant,
    Signal,
    Sine,
    Square,
    Step,
    automatic_square,
    parse_signal,
)

T = np.arange(0, 2000, dtype=np.float64)


def test_constant() -> None:
    s = parse_signal("const:-2.5")
    assert s == Constant(-2.5)
    assert_array_equal(s.sample(T[:5]), np.full(5, -2.5))
    assert s.value(1e6) == -2.5
    assert s.spec == "const:-2.5"


def test_step_edge_is_half_open() -> None:
    s = Step(0.0, 10.0, at=1.0)
    assert s.value(0.0) == 0.0
    assert s.value(np.nextafter(1.0, 0.0) - 1e-6) == 0.0
    assert s.value(1.0) == 10.0
    # 0.1 * 10 is 1.0000000000000002 or 0.9999999999999999 depending on the route:
    # both count as the edge.
    assert s.value(sum([0.1] * 10)) == 10.0
    assert_array_equal(s.sample([0, 1, 2]), [0.0, 10.0, 10.0])


def test_cooling_step() -> None:
    s = parse_signal("step:10:-10@100")
    assert s.value(99.0) == 10.0
    assert s.value(100.0) == -10.0


def test_square_phase_and_edges() -> None:
    s = Square(4.0, 6.0, 0.1)
    values = s.sample(T[:40])
    # HIGH on [10n, 10n + 5), LOW on [10n + 5, 10n + 10): five samples each at dt = 1 s.
    expected = np.tile([6.0] * 5 + [4.0] * 5, 4)
    assert_array_equal(values, expected)
    assert s.value(4.999) == 6.0
    assert s.value(5.0) == 4.0
    assert s.value(10.0) == 6.0


def test_square_edges_hold_for_long_runs_at_fractional_dt() -> None:
    # t = k * 0.1 accumulates rounding; every edge must still land on its sample.
    dt = 0.1
    k = np.arange(200_000)
    values = Square(0.0, 4.0, 1.0 / (10 * dt)).sample(k * dt)
    expected = np.where((k // 5) % 2 == 0, 4.0, 0.0)
    assert_array_equal(values, expected)


def test_automatic_square_is_a_tenth_of_the_sampling_frequency() -> None:
    s = automatic_square(4.0, 6.0, dt=1.0)
    assert s == Square(4.0, 6.0, 0.1)
    assert automatic_square(0.0, 4.0, dt=0.5).freq_hz == pytest.approx(0.2, rel=1e-15)
    with pytest.raises(InvalidParameterError, match="dt"):
        automatic_square(0.0, 4.0, dt=0.0)


def test_sine_and_clipping() -> None:
    s = Sine(5.0, 2.0, 0.25)
    assert_allclose(s.sample([0.0, 1.0, 2.0, 3.0]), [5.0, 7.0, 5.0, 3.0], atol=1e-12)
    clipped = parse_signal("sine:8:4:0.01").sample(np.linspace(0, 100, 1001))
    assert clipped.max() == 10.0
    assert clipped.min() == pytest.approx(4.0, abs=1e-9)
    narrow = parse_signal("sine:0:5:0.25", limits=(-1.0, 2.0))
    assert narrow.value(1.0) == 2.0
    assert narrow.value(3.0) == -1.0


def test_prbs_is_deterministic_binary_and_bitwise_constant() -> None:
    s = parse_signal("prbs:0:4:5:42")
    values = s.sample(T)
    assert set(np.unique(values)) == {0.0, 4.0}
    assert_array_equal(values, PRBS(0.0, 4.0, 5.0, 42).sample(T))
    # Constant within each 5 s bit.
    assert_array_equal(values.reshape(-1, 5), np.repeat(values[::5, None], 5, axis=1))
    # Different seeds start the sequence in different places.
    assert not np.array_equal(values, parse_signal("prbs:0:4:5:43").sample(T))
    # Each scalar value agrees with the vector form.
    assert all(s.value(t) == v for t, v in zip(T[:60], values[:60], strict=True))


def test_prbs_is_a_maximum_length_sequence() -> None:
    s = PRBS(-1.0, 1.0, 1.0, seed=7)
    period = 2**15 - 1
    bits = s.sample(np.arange(2 * period, dtype=np.float64))
    assert_array_equal(bits[:period], bits[period:])
    # An MLS has one more 1 than 0 over a period, and a two-valued autocorrelation.
    assert int(np.sum(bits[:period] > 0)) == 2**14
    one_period = bits[:period]
    for lag in (1, 2, 17, 1000):
        assert int(np.dot(one_period, np.roll(one_period, lag))) == -1


def test_signals_are_immutable() -> None:
    s = Square(4.0, 6.0, 0.1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.low = 0.0  # type: ignore[misc]


def test_sample_keeps_shape() -> None:
    grid = np.zeros((3, 4))
    assert Constant(1.0).sample(grid).shape == (3, 4)
    assert isinstance(Constant(1.0).value(0), float)


_level = st.floats(-10, 10, allow_nan=False).map(lambda v: round(v, 6))
_positive = st.floats(1e-3, 1e3).map(lambda v: round(v, 6)).filter(lambda v: v > 0)


@st.composite
def _signals(draw: st.DrawFn) -> Signal:
    kind = draw(st.sampled_from(["const", "step", "square", "sine", "prbs"]))
    a, b = sorted([draw(_level), draw(_level)])
    if kind == "const":
        return Constant(a)
    if kind == "step":
        return Step(draw(_level), draw(_level), draw(st.floats(0, 1e4)))
    if kind == "square":
        return Square(a, b, draw(_positive))
    if kind == "sine":
        return Sine(a, draw(st.floats(0, 20)), draw(_positive))
    return PRBS(a, b, draw(_positive), draw(st.integers(0, 2**40)))


@settings(max_examples=80, deadline=None)
@given(_signals())
def test_spec_round_trips(signal: Signal) -> None:
    parsed = parse_signal(signal.spec)
    assert parsed == signal
    assert parsed.spec == signal.spec
    assert str(signal) == signal.spec


@settings(max_examples=50, deadline=None)
@given(_signals(), st.lists(st.floats(0, 1e5), min_size=1, max_size=20))
def test_values_stay_inside_limits(signal: Signal, times: list[float]) -> None:
    values = signal.sample(times)
    assert np.all(values >= -10.0)
    assert np.all(values <= 10.0)


def test_canonical_spec_normalises_numbers_and_case() -> None:
    assert parse_signal("SQUARE: 4.0 :6.00: 0.10").spec == "square:4:6:0.1"
    assert parse_signal("step:0:10.0@1.0").spec == "step:0:10@1"
    assert parse_signal("prbs:0:4:5").spec == "prbs:0:4:5:0"
    assert parse_signal("sine:5:1e-3:0.5").spec == "sine:5:0.001:0.5"


def test_limits_are_kept_and_checked() -> None:
    s = parse_signal("const:12", limits=(0.0, 24.0))
    assert s.limits == (0.0, 24.0)
    assert parse_signal(s.spec, limits=s.limits) == s
    with pytest.raises(SignalSpecError, match="limits must be finite with low < high"):
        parse_signal("const:1", limits=(5.0, -5.0))


@pytest.mark.parametrize(
    ("spec", "problem"),
    [
        ("", "expected KIND:VALUES"),
        ("square", "expected KIND:VALUES"),
        ("triangle:1:2:3", "unknown kind 'triangle'"),
        ("const:", "U must be a number, got ''"),
        ("const:1:2", "const needs 1 value U, got 2"),
        ("const:abc", "U must be a number, got 'abc'"),
        ("const:nan", "U must be finite, got 'nan'"),
        ("const:1_0", "U must be a number, got '1_0'"),
        ("const:11", r"level = 11 V is outside the input range \[-10, 10\] V"),
        ("step:0:10", "step needs U0:U1@T"),
        ("step:0:10@", "T must be a number, got ''"),
        ("step:0:10@-5", "at must be >= 0 s, got -5"),
        ("step:0:10@1@2", "step needs U0:U1@T"),
        ("square:4:6", "square needs 3 values LOW:HIGH:FREQ_HZ, got 2"),
        ("square:6:4:0.1", r"LOW \(6\) must not exceed HIGH \(4\)"),
        ("square:4:6:0", "freq_hz must be > 0 Hz, got 0"),
        ("square:4:16:0.1", r"high = 16 V is outside the input range"),
        ("sine:5:-1:0.1", "amplitude must be >= 0 V, got -1"),
        ("sine:5:1:inf", "FREQ_HZ must be finite, got 'inf'"),
        ("prbs:0:4", "prbs needs 3 or 4 values LOW:HIGH:BIT_SECONDS"),
        ("prbs:0:4:0:1", "bit_seconds must be > 0 s, got 0"),
        ("prbs:0:4:5:-1", "SEED must be a non-negative integer, got '-1'"),
        ("prbs:0:4:5:1.5", "SEED must be a non-negative integer, got '1.5'"),
    ],
)
def test_bad_specs_say_what_is_wrong(spec: str, problem: str) -> None:
    with pytest.raises(SignalSpecError, match=problem) as exc:
        parse_signal(spec)
    message = str(exc.value)
    assert message.startswith(f"invalid signal {spec!r}: ")
    assert message.endswith(f"accepted forms: {SIGNAL_SYNTAX}")
    assert "\n" not in message


def test_non_text_spec() -> None:
    with pytest.raises(SignalSpecError, match="must be text, got int"):
        parse_signal(3)  # type: ignore[arg-type]


def test_constructor_errors_are_parameter_errors() -> None:
    with pytest.raises(InvalidParameterError, match="freq_hz must be > 0"):
        Square(0.0, 1.0, -1.0)
    with pytest.raises(InvalidParameterError, match="SEED must be a non-negative integer"):
        PRBS(0.0, 1.0, 1.0, seed=True)
    with pytest.raises(InvalidParameterError, match="limits must be a pair"):
        Constant(0.0, limits=(1.0,))  # type: ignore[arg-type]


def test_bad_times() -> None:
    with pytest.raises(InvalidParameterError, match="finite"):
        Constant(0.0).sample([0.0, math.nan])
    with pytest.raises(InvalidParameterError, match="finite"):
        Constant(0.0).value(math.inf)
