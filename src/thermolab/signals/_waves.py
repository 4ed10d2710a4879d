"""The deterministic signal families: constant, step, square wave and sine.

With :func:`automatic_square`, the paper's *Automatic* input. Re-exported by
:mod:`thermolab.signals`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from thermolab.errors import InvalidParameterError

from ._base import (
    DEFAULT_LIMITS,
    EDGE_TOL,
    FloatArray,
    Signal,
    check_level,
    check_number,
    edge_index,
    fmt,
)

__all__ = ["Constant", "Sine", "Square", "Step", "automatic_square"]


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
        check_level(self, "level", self.level)

    @property
    def spec(self) -> str:
        """Canonical text ``const:U``."""
        return f"const:{fmt(self.level)}"

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
        check_level(self, "before", self.before)
        check_level(self, "after", self.after)
        check_number(self, "at", self.at, minimum=0.0, inclusive=True, unit="s")

    @property
    def spec(self) -> str:
        """Canonical text ``step:U0:U1@T``."""
        return f"step:{fmt(self.before)}:{fmt(self.after)}@{fmt(self.at)}"

    def _raw(self, t: FloatArray) -> FloatArray:
        scale = max(1.0, abs(self.at))
        after = t >= self.at - EDGE_TOL * scale
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
        check_level(self, "low", self.low)
        check_level(self, "high", self.high)
        if self.low > self.high:
            raise InvalidParameterError(
                f"square wave: LOW ({fmt(self.low)}) must not exceed HIGH ({fmt(self.high)})"
            )
        check_number(self, "freq_hz", self.freq_hz, minimum=0.0, inclusive=False, unit="Hz")

    @property
    def spec(self) -> str:
        """Canonical text ``square:LOW:HIGH:FREQ_HZ``."""
        return f"square:{fmt(self.low)}:{fmt(self.high)}:{fmt(self.freq_hz)}"

    def _raw(self, t: FloatArray) -> FloatArray:
        half_periods = edge_index(t * (2.0 * self.freq_hz))
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
        check_level(self, "offset", self.offset)
        check_number(self, "amplitude", self.amplitude, minimum=0.0, inclusive=True, unit="V")
        check_number(self, "freq_hz", self.freq_hz, minimum=0.0, inclusive=False, unit="Hz")

    @property
    def spec(self) -> str:
        """Canonical text ``sine:OFFSET:AMPLITUDE:FREQ_HZ``."""
        return f"sine:{fmt(self.offset)}:{fmt(self.amplitude)}:{fmt(self.freq_hz)}"

    def _raw(self, t: FloatArray) -> FloatArray:
        return self.offset + self.amplitude * np.sin(2.0 * np.pi * self.freq_hz * t)


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
