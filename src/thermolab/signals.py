"""Excitation signals and their text syntax.

Five generators drive the rig's input: a constant, a step, a square wave (the
paper's *Automatic* option), a sine and a pseudo-random binary sequence. Each
is an immutable :class:`Signal` with ``value(t)`` (one time),
``sample(t_array)`` (many) and ``spec``, its canonical text in the one syntax
shared by the command line and the server::

    const:U                           constant U volts
    step:U0:U1@T                      U0 before T seconds, U1 from T on
    square:LOW:HIGH:FREQ_HZ           square wave, HIGH for the first half period
    sine:OFFSET:AMPLITUDE:FREQ_HZ     OFFSET + AMPLITUDE sin(2 pi FREQ_HZ t)
    prbs:LOW:HIGH:BIT_SECONDS[:SEED]  maximum-length PRBS, one bit per BIT_SECONDS

:func:`parse_signal` reads that syntax; ``parse_signal(s.spec, s.limits) == s``
for every signal ``s``.

Time ``t`` is in seconds from the start of the run. Values are volts and never
leave the input range ``limits`` (±10 V, the paper's rig, by default): the
levels a signal is built from must lie inside it (an out-of-range level is an
error, not silently changed), and the excursions of a sine beyond it are
clipped.

Edges. Steps, square-wave edges and PRBS bit boundaries are half-open: the
new level holds *at* the edge time. Times are computed in floating point
(``k * dt``), so a time within about 1e-9 of an edge (relative to the edge
spacing) counts as at the edge; sampled at ``t = k dt`` every edge lands on the
sample it is meant for.
"""

from __future__ import annotations

import functools
import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.signal import max_len_seq

from thermolab.errors import InvalidParameterError, SignalSpecError

__all__ = [
    "DEFAULT_LIMITS",
    "PRBS",
    "SIGNAL_SYNTAX",
    "Constant",
    "Signal",
    "Sine",
    "Square",
    "Step",
    "automatic_square",
    "parse_signal",
]

FloatArray = npt.NDArray[np.float64]

#: The rig's input range in volts (the paper's ±10 V).
DEFAULT_LIMITS: tuple[float, float] = (-10.0, 10.0)

#: The accepted forms of a signal specification, as shown in error messages.
SIGNAL_SYNTAX = (
    "const:U, step:U0:U1@T, square:LOW:HIGH:FREQ_HZ, sine:OFFSET:AMPLITUDE:FREQ_HZ, "
    "prbs:LOW:HIGH:BIT_SECONDS[:SEED]"
)

_Fail = Callable[[str], SignalSpecError]

# Register length of the PRBS: a period of 32767 bits (the ITU PRBS15 length), far
# longer than any run, yet small enough to tabulate once per seed.
_PRBS_BITS = 15
# Relative tolerance for a time landing on an edge (see the module notes).
_EDGE_TOL = 1e-9


@dataclass(frozen=True)
class Signal(ABC):
    """An excitation signal: volts as a function of time in seconds.

    Parameters
    ----------
    limits : tuple of float, keyword-only
        The input range ``(low, high)`` in volts; every value lies inside it.

    Notes
    -----
    Subclasses are frozen dataclasses and compare by value; build them directly
    (:class:`Step` ...) or from text with :func:`parse_signal`.

    Examples
    --------
    >>> s = Step(0.0, 10.0, at=1.0)
    >>> s.value(0.5), s.value(1.0)
    (0.0, 10.0)
    >>> s.sample([0.0, 1.0, 2.0])
    array([ 0., 10., 10.])
    >>> s.spec
    'step:0:10@1'
    """

    limits: tuple[float, float] = field(default=DEFAULT_LIMITS, kw_only=True)

    def __post_init__(self) -> None:
        lo, hi = _limits(self.limits)
        object.__setattr__(self, "limits", (lo, hi))
        self._validate()

    @property
    @abstractmethod
    def spec(self) -> str:
        """The canonical text of this signal (see :func:`parse_signal`)."""

    @abstractmethod
    def _validate(self) -> None:
        """Check the fields; raise InvalidParameterError naming the bad one."""

    @abstractmethod
    def _raw(self, t: FloatArray) -> FloatArray:
        """Unclipped values at the times ``t``."""

    def sample(self, t: npt.ArrayLike) -> FloatArray:
        """Return the signal at each time of ``t``.

        Parameters
        ----------
        t : array_like
            Times in seconds (any shape), finite.

        Returns
        -------
        numpy.ndarray
            Volts, float64, the shape of ``t``, inside ``limits``.

        Raises
        ------
        InvalidParameterError
            If a time is not a finite number.

        Examples
        --------
        >>> Square(4.0, 6.0, 0.1).sample([0, 4, 5, 9, 10])
        array([6., 6., 4., 4., 6.])
        """
        try:
            times = np.asarray(t, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InvalidParameterError(f"times must be numbers: {exc}") from None
        if not np.all(np.isfinite(times)):
            raise InvalidParameterError("times must be finite numbers of seconds")
        return np.clip(self._raw(times), self.limits[0], self.limits[1])

    def value(self, t: float) -> float:
        """Return the signal at time ``t`` (seconds).

        Parameters
        ----------
        t : float
            Time in seconds, finite.

        Returns
        -------
        float
            Volts, inside ``limits``.

        Raises
        ------
        InvalidParameterError
            If ``t`` is not a finite number.

        Examples
        --------
        >>> Constant(2.5).value(100.0)
        2.5
        """
        return float(self.sample(np.array([t], dtype=np.float64))[0])

    def __str__(self) -> str:
        return self.spec


@dataclass(frozen=True)
class Constant(Signal):
    """A constant input.

    Parameters
    ----------
    level : float
        Volts, inside ``limits``.
    limits : tuple of float, keyword-only
        Input range (default ±10 V).

    Raises
    ------
    InvalidParameterError
        If ``level`` is not finite or outside ``limits``.

    Examples
    --------
    >>> Constant(3.0).spec
    'const:3'
    """

    level: float

    def _validate(self) -> None:
        _level(self, "level", self.level)

    @property
    def spec(self) -> str:
        """Canonical text ``const:U``."""
        return f"const:{_fmt(self.level)}"

    def _raw(self, t: FloatArray) -> FloatArray:
        return np.full(t.shape, self.level)


@dataclass(frozen=True)
class Step(Signal):
    """A step from ``before`` to ``after`` at time ``at``.

    Parameters
    ----------
    before, after : float
        Volts before ``at`` and from ``at`` on, inside ``limits``.
    at : float
        Step time in seconds, >= 0; the value at ``at`` itself is ``after``.
    limits : tuple of float, keyword-only
        Input range (default ±10 V).

    Raises
    ------
    InvalidParameterError
        If a level is outside ``limits`` or ``at`` is negative or not finite.

    Examples
    --------
    >>> Step(0.0, 10.0, at=1.0).sample([0.0, 0.999, 1.0, 1500.0])
    array([ 0.,  0., 10., 10.])
    """

    before: float
    after: float
    at: float = 0.0

    def _validate(self) -> None:
        _level(self, "before", self.before)
        _level(self, "after", self.after)
        _number(self, "at", self.at, minimum=0.0, inclusive=True, unit="s")

    @property
    def spec(self) -> str:
        """Canonical text ``step:U0:U1@T``."""
        return f"step:{_fmt(self.before)}:{_fmt(self.after)}@{_fmt(self.at)}"

    def _raw(self, t: FloatArray) -> FloatArray:
        scale = max(1.0, abs(self.at))
        after = t >= self.at - _EDGE_TOL * scale
        return np.where(after, self.after, self.before)


@dataclass(frozen=True)
class Square(Signal):
    """A square wave between ``low`` and ``high``, starting at ``high``.

    Parameters
    ----------
    low, high : float
        The two levels in volts, ``low <= high``, inside ``limits``.
    freq_hz : float
        Frequency in hertz, > 0 (period ``1 / freq_hz``).
    limits : tuple of float, keyword-only
        Input range (default ±10 V).

    Raises
    ------
    InvalidParameterError
        If a level is outside ``limits``, ``low > high`` or ``freq_hz <= 0``.

    Notes
    -----
    Phase: ``high`` on ``[n P, n P + P/2)`` and ``low`` on ``[n P + P/2, (n+1) P)``
    for every integer ``n``, ``P = 1 / freq_hz``. Starting at ``high`` makes the
    first move from a rig resting at the low level (or at 0 V) upward, as in the
    paper's runs. Each edge belongs to the half period it starts.

    Examples
    --------
    The paper's 4↔6 V at 0.1 Hz: six volts for 5 s, then four for 5 s.

    >>> Square(4.0, 6.0, 0.1).sample(range(11))
    array([6., 6., 6., 6., 6., 4., 4., 4., 4., 4., 6.])
    """

    low: float
    high: float
    freq_hz: float

    def _validate(self) -> None:
        _level(self, "low", self.low)
        _level(self, "high", self.high)
        if self.low > self.high:
            raise InvalidParameterError(
                f"square wave: LOW ({_fmt(self.low)}) must not exceed HIGH ({_fmt(self.high)})"
            )
        _number(self, "freq_hz", self.freq_hz, minimum=0.0, inclusive=False, unit="Hz")

    @property
    def spec(self) -> str:
        """Canonical text ``square:LOW:HIGH:FREQ_HZ``."""
        return f"square:{_fmt(self.low)}:{_fmt(self.high)}:{_fmt(self.freq_hz)}"

    def _raw(self, t: FloatArray) -> FloatArray:
        half_periods = _edge_index(t * (2.0 * self.freq_hz))
        return np.where(half_periods % 2 == 0, self.high, self.low)


@dataclass(frozen=True)
class Sine(Signal):
    """A sine ``offset + amplitude sin(2 pi freq_hz t)``, clipped to ``limits``.

    Parameters
    ----------
    offset : float
        Mean level in volts, inside ``limits``.
    amplitude : float
        Peak deviation in volts, >= 0; peaks beyond ``limits`` are clipped.
    freq_hz : float
        Frequency in hertz, > 0.
    limits : tuple of float, keyword-only
        Input range (default ±10 V).

    Raises
    ------
    InvalidParameterError
        If ``offset`` is outside ``limits``, ``amplitude < 0`` or ``freq_hz <= 0``.

    Examples
    --------
    >>> Sine(5.0, 2.0, 0.25).sample([0.0, 1.0, 2.0, 3.0]).round(12)
    array([5., 7., 5., 3.])
    >>> Sine(8.0, 4.0, 0.25).value(1.0)  # 12 V clipped to the 10 V limit
    10.0
    """

    offset: float
    amplitude: float
    freq_hz: float

    def _validate(self) -> None:
        _level(self, "offset", self.offset)
        _number(self, "amplitude", self.amplitude, minimum=0.0, inclusive=True, unit="V")
        _number(self, "freq_hz", self.freq_hz, minimum=0.0, inclusive=False, unit="Hz")

    @property
    def spec(self) -> str:
        """Canonical text ``sine:OFFSET:AMPLITUDE:FREQ_HZ``."""
        return f"sine:{_fmt(self.offset)}:{_fmt(self.amplitude)}:{_fmt(self.freq_hz)}"

    def _raw(self, t: FloatArray) -> FloatArray:
        return self.offset + self.amplitude * np.sin(2.0 * np.pi * self.freq_hz * t)


@dataclass(frozen=True)
class PRBS(Signal):
    """A maximum-length pseudo-random binary sequence between ``low`` and ``high``.

    Parameters
    ----------
    low, high : float
        The two levels in volts, ``low <= high``, inside ``limits``.
    bit_seconds : float
        Duration of one bit in seconds, > 0.
    seed : int, optional
        Non-negative integer choosing the sequence's starting state (default 0).
        The same seed always gives the same signal, on every machine.
    limits : tuple of float, keyword-only
        Input range (default ±10 V).

    Raises
    ------
    InvalidParameterError
        If a level is outside ``limits``, ``low > high``, ``bit_seconds <= 0`` or
        ``seed`` is not a non-negative integer.

    Notes
    -----
    The bits are a 15-bit maximum-length sequence (period 32767 bits, from
    :func:`scipy.signal.max_len_seq`): its autocorrelation is flat, which is what
    makes a PRBS a good identification input. The seed is hashed (SplitMix64)
    into the register's non-zero starting state. Bit ``i`` covers
    ``[i bit_seconds, (i+1) bit_seconds)``; a 1 bit is ``high``.

    Examples
    --------
    >>> s = PRBS(0.0, 4.0, bit_seconds=5.0, seed=3)
    >>> s.spec
    'prbs:0:4:5:3'
    >>> bool(np.all(s.sample([0.0, 1.0, 4.9]) == s.value(0.0)))
    True
    """

    low: float
    high: float
    bit_seconds: float
    seed: int = 0
    _bits: npt.NDArray[np.bool_] = field(init=False, repr=False, compare=False)

    def _validate(self) -> None:
        _level(self, "low", self.low)
        _level(self, "high", self.high)
        if self.low > self.high:
            raise InvalidParameterError(
                f"PRBS: LOW ({_fmt(self.low)}) must not exceed HIGH ({_fmt(self.high)})"
            )
        _number(self, "bit_seconds", self.bit_seconds, minimum=0.0, inclusive=False, unit="s")
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int | np.integer)
            or self.seed < 0
        ):
            raise InvalidParameterError(
                f"PRBS: SEED must be a non-negative integer, got {self.seed!r}"
            )
        object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "_bits", _mls_bits(self.seed))

    @property
    def spec(self) -> str:
        """Canonical text ``prbs:LOW:HIGH:BIT_SECONDS:SEED`` (the seed always shown)."""
        return f"prbs:{_fmt(self.low)}:{_fmt(self.high)}:{_fmt(self.bit_seconds)}:{self.seed}"

    def _raw(self, t: FloatArray) -> FloatArray:
        index = _edge_index(t / self.bit_seconds) % self._bits.size
        return np.where(self._bits[index], self.high, self.low)


def automatic_square(
    low: float, high: float, dt: float, *, limits: tuple[float, float] = DEFAULT_LIMITS
) -> Square:
    """The paper's *Automatic* input: a square wave at a tenth of the sampling frequency.

    Parameters
    ----------
    low, high : float
        Minimum and maximum volts, ``low <= high``.
    dt : float
        Sample period in seconds, > 0; the wave's period is ``10 dt``.
    limits : tuple of float, keyword-only
        Input range (default ±10 V).

    Returns
    -------
    Square
        ``Square(low, high, 1 / (10 dt))``, starting at ``high``.

    Raises
    ------
    InvalidParameterError
        If ``dt <= 0`` or the levels are invalid for :class:`Square`.

    Examples
    --------
    >>> automatic_square(4.0, 6.0, dt=1.0).spec
    'square:4:6:0.1'
    """
    if (
        isinstance(dt, bool)
        or not isinstance(dt, int | float)
        or not (math.isfinite(dt) and dt > 0)
    ):
        raise InvalidParameterError(f"dt (sample period) must be > 0 seconds, got {dt!r}")
    return Square(low, high, 1.0 / (10.0 * dt), limits=limits)


def parse_signal(spec: str, limits: tuple[float, float] = DEFAULT_LIMITS) -> Signal:
    """Parse a signal specification (see the module notes for the syntax).

    Parameters
    ----------
    spec : str
        ``const:U``, ``step:U0:U1@T``, ``square:LOW:HIGH:FREQ_HZ``,
        ``sine:OFFSET:AMPLITUDE:FREQ_HZ`` or ``prbs:LOW:HIGH:BIT_SECONDS[:SEED]``;
        volts, seconds and hertz. The kind is case-insensitive and spaces around
        fields are ignored.
    limits : tuple of float, optional
        The input range; levels outside it are refused. Default ±10 V.

    Returns
    -------
    Signal
        A :class:`Constant`, :class:`Step`, :class:`Square`, :class:`Sine` or
        :class:`PRBS`, whose ``spec`` is the canonical form of ``spec``.

    Raises
    ------
    SignalSpecError
        Naming exactly what is wrong and listing the accepted forms.

    Examples
    --------
    >>> parse_signal("square:4:6:0.1")
    Square(limits=(-10.0, 10.0), low=4.0, high=6.0, freq_hz=0.1)
    >>> parse_signal(" STEP : 0 : 10.0 @ 1 ").spec
    'step:0:10@1'
    >>> parse_signal("prbs:0:4:5").spec
    'prbs:0:4:5:0'
    >>> parse_signal("square:4:6")
    Traceback (most recent call last):
    ...
    thermolab.errors.SignalSpecError: invalid signal 'square:4:6': square needs 3 values \
LOW:HIGH:FREQ_HZ, got 2; accepted forms: ...
    """
    if not isinstance(spec, str):
        raise SignalSpecError(
            f"a signal specification must be text, got {type(spec).__name__}; "
            f"accepted forms: {SIGNAL_SYNTAX}"
        )
    try:
        lo, hi = _limits(limits)
    except InvalidParameterError as exc:
        raise SignalSpecError(str(exc)) from None

    def fail(problem: str) -> SignalSpecError:
        return SignalSpecError(
            f"invalid signal {spec!r}: {problem}; accepted forms: {SIGNAL_SYNTAX}"
        )

    kind, sep, rest = spec.strip().partition(":")
    kind = kind.strip().lower()
    if not sep or not kind:
        raise fail("expected KIND:VALUES")
    fields = [f.strip() for f in rest.split(":")]
    try:
        if kind == "const":
            (u,) = _fields(fields, 1, "U", kind, fail)
            return Constant(_float(u, "U", fail), limits=(lo, hi))
        if kind == "step":
            if len(fields) != 2 or fields[1].count("@") != 1:
                raise fail("step needs U0:U1@T (the step time after '@')")
            u1_text, _, t_text = fields[1].partition("@")
            return Step(
                _float(fields[0], "U0", fail),
                _float(u1_text.strip(), "U1", fail),
                _float(t_text.strip(), "T", fail),
                limits=(lo, hi),
            )
        if kind == "square":
            low, high, freq = _fields(fields, 3, "LOW:HIGH:FREQ_HZ", kind, fail)
            return Square(
                _float(low, "LOW", fail),
                _float(high, "HIGH", fail),
                _float(freq, "FREQ_HZ", fail),
                limits=(lo, hi),
            )
        if kind == "sine":
            off, amp, freq = _fields(fields, 3, "OFFSET:AMPLITUDE:FREQ_HZ", kind, fail)
            return Sine(
                _float(off, "OFFSET", fail),
                _float(amp, "AMPLITUDE", fail),
                _float(freq, "FREQ_HZ", fail),
                limits=(lo, hi),
            )
        if kind == "prbs":
            if len(fields) not in (3, 4):
                raise fail(
                    f"prbs needs 3 or 4 values LOW:HIGH:BIT_SECONDS[:SEED], got {len(fields)}"
                )
            seed = 0
            if len(fields) == 4:
                if not (fields[3].isascii() and fields[3].isdigit()):
                    raise fail(f"SEED must be a non-negative integer, got {fields[3]!r}")
                seed = int(fields[3])
            return PRBS(
                _float(fields[0], "LOW", fail),
                _float(fields[1], "HIGH", fail),
                _float(fields[2], "BIT_SECONDS", fail),
                seed,
                limits=(lo, hi),
            )
    except SignalSpecError:
        raise
    except InvalidParameterError as exc:
        raise fail(str(exc)) from None
    raise fail(f"unknown kind {kind!r}")


def _fields(fields: list[str], n: int, names: str, kind: str, fail: _Fail) -> list[str]:
    if len(fields) != n:
        plural = "value" if n == 1 else "values"
        raise fail(f"{kind} needs {n} {plural} {names}, got {len(fields)}")
    return fields


def _float(text: str, name: str, fail: _Fail) -> float:
    try:
        # float() would also take '1_0' and 'infinity'; accept plain decimal numbers only.
        if not text or "_" in text:
            raise ValueError
        value = float(text)
    except ValueError:
        raise fail(f"{name} must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise fail(f"{name} must be finite, got {text!r}")
    return value


def _limits(limits: object) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in limits)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise InvalidParameterError(
            f"limits must be a pair (low, high) of volts, got {limits!r}"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise InvalidParameterError(f"limits must be finite with low < high, got ({lo!r}, {hi!r})")
    return lo, hi


def _level(signal: Signal, name: str, value: object) -> None:
    v = _number(signal, name, value)
    lo, hi = signal.limits
    if not lo <= v <= hi:
        raise InvalidParameterError(
            f"{name} = {_fmt(v)} V is outside the input range [{_fmt(lo)}, {_fmt(hi)}] V"
        )


def _number(
    signal: Signal,
    name: str,
    value: object,
    *,
    minimum: float | None = None,
    inclusive: bool = True,
    unit: str = "V",
) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidParameterError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise InvalidParameterError(f"{name} must be finite, got {v!r}")
    if minimum is not None and (v < minimum or (v == minimum and not inclusive)):
        op = ">=" if inclusive else ">"
        raise InvalidParameterError(f"{name} must be {op} {_fmt(minimum)} {unit}, got {_fmt(v)}")
    object.__setattr__(signal, name, v)
    return v


def _fmt(x: float) -> str:
    """Shortest text that reads back as ``x``: 4.0 -> '4', 0.1 -> '0.1'."""
    if x == 0.0:
        return "0"
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(float(x))


def _edge_index(x: FloatArray) -> npt.NDArray[np.int64]:
    """``floor(x)``, with values a rounding error below an integer counted as on it."""
    nearest = np.rint(x)
    on_edge = np.abs(x - nearest) <= _EDGE_TOL * np.maximum(1.0, np.abs(x))
    return np.floor(np.where(on_edge, nearest, x)).astype(np.int64)


@functools.lru_cache(maxsize=64)
def _mls_bits(seed: int) -> npt.NDArray[np.bool_]:
    state = _splitmix64(seed) & ((1 << _PRBS_BITS) - 1) or 1
    register = np.array([(state >> i) & 1 for i in range(_PRBS_BITS)], dtype=np.int8)
    seq, _ = max_len_seq(_PRBS_BITS, state=register)
    bits = np.asarray(seq, dtype=bool)
    bits.setflags(write=False)
    return bits


def _splitmix64(seed: int) -> int:
    mask = (1 << 64) - 1
    z = (seed + 0x9E3779B97F4A7C15) & mask
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
    return z ^ (z >> 31)
