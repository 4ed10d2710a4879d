"""The base of every excitation signal: :class:`Signal`, its input range and checks.

Shared by the signal families (:mod:`thermolab.signals._waves`,
:mod:`thermolab.signals._prbs`) and the text syntax
(:mod:`thermolab.signals._syntax`); the public names are re-exported by
:mod:`thermolab.signals`, which also states the edge convention implemented
here (:func:`edge_index`).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError

__all__ = ["DEFAULT_LIMITS", "Signal"]

FloatArray = npt.NDArray[np.float64]

#: The rig's input range in volts (the paper's ±10 V).
DEFAULT_LIMITS: tuple[float, float] = (-10.0, 10.0)

# Relative tolerance for a time landing on an edge (see thermolab.signals' notes).
EDGE_TOL = 1e-9


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
    >>> from thermolab.signals import Step
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
        lo, hi = check_limits(self.limits)
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
        >>> from thermolab.signals import Square
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
        >>> from thermolab.signals import Constant
        >>> Constant(2.5).value(100.0)
        2.5
        """
        return float(self.sample(np.array([t], dtype=np.float64))[0])

    def __str__(self) -> str:
        return self.spec


def check_limits(limits: object) -> tuple[float, float]:
    """The input range ``(low, high)`` as floats, or InvalidParameterError naming the problem."""
    try:
        lo, hi = (float(v) for v in limits)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise InvalidParameterError(
            f"limits must be a pair (low, high) of volts, got {limits!r}"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise InvalidParameterError(f"limits must be finite with low < high, got ({lo!r}, {hi!r})")
    return lo, hi


def check_level(signal: Signal, name: str, value: object) -> None:
    """Check (and store as float) a level in volts that must lie inside ``signal.limits``."""
    v = check_number(signal, name, value)
    lo, hi = signal.limits
    if not lo <= v <= hi:
        raise InvalidParameterError(
            f"{name} = {fmt(v)} V is outside the input range [{fmt(lo)}, {fmt(hi)}] V"
        )


def check_number(
    signal: Signal,
    name: str,
    value: object,
    *,
    minimum: float | None = None,
    inclusive: bool = True,
    unit: str = "V",
) -> float:
    """Check (and store as float) a finite number field, optionally bounded below."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidParameterError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise InvalidParameterError(f"{name} must be finite, got {v!r}")
    if minimum is not None and (v < minimum or (v == minimum and not inclusive)):
        op = ">=" if inclusive else ">"
        raise InvalidParameterError(f"{name} must be {op} {fmt(minimum)} {unit}, got {fmt(v)}")
    object.__setattr__(signal, name, v)
    return v


def fmt(x: float) -> str:
    """Shortest text that reads back as ``x``: 4.0 -> '4', 0.1 -> '0.1'."""
    if x == 0.0:
        return "0"
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(float(x))


def edge_index(x: FloatArray) -> npt.NDArray[np.int64]:
    """``floor(x)``, with values a rounding error below an integer counted as on it."""
    nearest = np.rint(x)
    on_edge = np.abs(x - nearest) <= EDGE_TOL * np.maximum(1.0, np.abs(x))
    return np.floor(np.where(on_edge, nearest, x)).astype(np.int64)
