"""The discrete PID law: state, limits, anti-windup, bumpless transfer.

The controller is the textbook parallel (ISA) form

.. math:: u = K_p \\left(e + \\frac{1}{T_i}\\int e\\,dt - T_d \\frac{dy_f}{dt}\\right),
          \\qquad e = r - y

discretised as in Åström & Murray, *Feedback Systems* (2008), §10.5:

* integral by forward Euler, updated after the output is computed;
* derivative on the measurement (a set-point step gives no derivative kick)
  through a first-order filter ``T_f = T_d / N``, backward difference (stable
  for every ``dt``);
* output clipped to ``[u_min, u_max]`` and **back-calculation** anti-windup:
  the integral is driven by ``(u - v) / T_t`` where ``v`` is the unclipped
  demand, with the tracking time ``T_t = sqrt(T_i T_d)`` (``T_i`` for a PI), the
  book's rule of thumb.

No threads and no clocks: the caller says ``dt`` at every call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from thermolab.control.words import LoopWord
from thermolab.errors import GainRangeError, InvalidParameterError

__all__ = ["GAIN_LIMITS", "PID", "GainRangeError", "PIDGains"]

#: The published ranges of the gains (inclusive): ``|Kp|`` in
#: ``[1e-6, 1e4]`` (input unit per output unit, sign = the plant's), ``Ti`` in
#: ``[1e-3, 1e6]`` s, ``Td`` in ``[0, 1e5]`` s. Wider values are typing errors,
#: not designs: a 1 s sample period cannot act on a 1 ms integral time.
GAIN_LIMITS: dict[str, tuple[float, float]] = {
    "kp": (1e-6, 1e4),
    "ti": (1e-3, 1e6),
    "td": (0.0, 1e5),
}


def _checked(name: str, value: object, *, magnitude: bool = False) -> float:
    low, high = GAIN_LIMITS[name]
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise GainRangeError(f"{name} must be a number, got {value!r}") from None
    size = abs(x) if magnitude else x
    if not (math.isfinite(x) and low <= size <= high):
        word = LoopWord.of(
            "gain_size_out_of_range" if magnitude else "gain_out_of_range",
            gain=name, low=low, high=high, value=x,
        )  # fmt: skip
        raise GainRangeError(word.text, word_code=word.code, word_params=word.params)
    return x


@dataclass(frozen=True, slots=True)
class PIDGains:
    """Gains of a PID in parallel form: ``Kp``, integral time ``Ti``, derivative time ``Td``.

    Parameters
    ----------
    Kp : float
        Proportional gain (input unit per output unit); negative for a plant
        whose gain is negative.
    Ti : float
        Integral time in seconds.
    Td : float, optional
        Derivative time in seconds (default 0: a PI).

    Raises
    ------
    InvalidParameterError
        If a gain is not finite or outside :data:`GAIN_LIMITS`.

    Examples
    --------
    >>> PIDGains(2.0, 100.0).to_dict()
    {'Kp': 2.0, 'Ti': 100.0, 'Td': 0.0}
    >>> PIDGains(float("nan"), 1.0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    thermolab.errors.GainRangeError: kp must be finite with |kp| in [1e-06, 10000], ...
    """

    Kp: float
    Ti: float
    Td: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "Kp", _checked("kp", self.Kp, magnitude=True))
        object.__setattr__(self, "Ti", _checked("ti", self.Ti))
        object.__setattr__(self, "Td", _checked("td", self.Td))

    def to_dict(self) -> dict[str, float]:
        """Return ``{"Kp", "Ti", "Td"}`` (JSON-ready)."""
        return {"Kp": self.Kp, "Ti": self.Ti, "Td": self.Td}


class PID:
    """A discrete PID controller with output limits, anti-windup and bumpless transfer.

    Parameters
    ----------
    gains : PIDGains
        The gains.
    u_min, u_max : float
        Output limits (the rig's input range), ``u_min < u_max``.
    derivative_filter : float, optional
        ``N`` of the derivative filter ``T_f = T_d / N`` (default 10).
    tracking_time : float, optional
        Back-calculation time ``T_t`` in seconds (default ``sqrt(Ti·Td)``, or
        ``Ti`` for a PI).

    Raises
    ------
    InvalidParameterError
        If the limits or the filter are not finite and ordered.

    Examples
    --------
    A proportional kick, then the integral at work on a constant error:

    >>> pid = PID(PIDGains(2.0, 10.0), 0.0, 100.0)
    >>> pid.update(setpoint=30.0, measurement=25.0, dt=1.0)
    10.0
    >>> pid.update(30.0, 25.0, 1.0)
    11.0

    At saturation the integral stops growing (back-calculation):

    >>> pid = PID(PIDGains(50.0, 10.0), 0.0, 100.0)
    >>> [pid.update(80.0, 20.0, 1.0) for _ in range(3)]
    [100.0, 100.0, 100.0]
    >>> pid.integral < 100.0
    True
    """

    def __init__(
        self,
        gains: PIDGains,
        u_min: float,
        u_max: float,
        *,
        derivative_filter: float = 10.0,
        tracking_time: float | None = None,
    ) -> None:
        if not isinstance(gains, PIDGains):
            raise InvalidParameterError(f"gains must be PIDGains, got {type(gains).__name__}")
        if not (math.isfinite(u_min) and math.isfinite(u_max) and u_min < u_max):
            raise InvalidParameterError(
                f"output limits must be finite with u_min < u_max, got [{u_min!r}, {u_max!r}]"
            )
        if not (math.isfinite(derivative_filter) and derivative_filter > 0):
            raise InvalidParameterError(
                f"derivative_filter (N) must be a positive number, got {derivative_filter!r}"
            )
        if tracking_time is not None and not (math.isfinite(tracking_time) and tracking_time > 0):
            raise InvalidParameterError(
                f"tracking_time must be a positive number of seconds, got {tracking_time!r}"
            )
        self.u_min = float(u_min)
        self.u_max = float(u_max)
        self.derivative_filter = float(derivative_filter)
        self._tracking_time = tracking_time
        self._gains = gains
        self.integral = 0.0
        self.derivative = 0.0
        self._last_y: float | None = None
        self.output = math.nan  # nothing computed or tracked yet

    @property
    def gains(self) -> PIDGains:
        """The gains in force."""
        return self._gains

    @property
    def tracking_time(self) -> float:
        """The back-calculation time ``T_t`` in seconds."""
        if self._tracking_time is not None:
            return self._tracking_time
        g = self._gains
        return math.sqrt(g.Ti * g.Td) if g.Td > 0 else g.Ti

    def set_gains(self, gains: PIDGains, setpoint: float, measurement: float) -> None:
        """Change the gains without a bump in the output.

        The integral is moved so that the new proportional part plus the
        integral gives the same output as before at this error.
        """
        if not isinstance(gains, PIDGains):
            raise InvalidParameterError(f"gains must be PIDGains, got {type(gains).__name__}")
        old_p = self._gains.Kp * (setpoint - measurement)
        self._gains = gains
        self.integral += old_p - gains.Kp * (setpoint - measurement)

    def track(self, u: float, setpoint: float, measurement: float) -> None:
        """Follow an output set elsewhere (manual mode) so that AUTO starts without a bump.

        Called once per sample while the loop is open: the integral takes the
        value that makes the next :meth:`update` return ``u`` at this error,
        and the derivative restarts from this measurement.
        """
        self.integral = float(u) - self._gains.Kp * (setpoint - measurement)
        self.derivative = 0.0
        self._last_y = float(measurement)
        self.output = float(u)

    def update(self, setpoint: float, measurement: float, dt: float) -> float:
        """Take one sample; return the output to apply until the next one.

        Parameters
        ----------
        setpoint, measurement : float
            ``r(k)`` and ``y(k)`` in the output unit.
        dt : float
            Seconds since the previous call (> 0).

        Returns
        -------
        float
            ``u(k)`` within ``[u_min, u_max]``.
        """
        g = self._gains
        e = setpoint - measurement
        if self._last_y is None:
            self.derivative = 0.0
        elif g.Td > 0:
            tf = g.Td / self.derivative_filter
            self.derivative = (
                tf * self.derivative - g.Kp * g.Td * (measurement - self._last_y)
            ) / (tf + dt)
        self._last_y = measurement
        demand = g.Kp * e + self.integral + self.derivative
        u = min(max(demand, self.u_min), self.u_max)
        # dt/Tt is capped at 1: a tracking time shorter than the period would overshoot the
        # reset (and a vanishing Td would make it infinite); at 1 the integral is reset so
        # that the demand equals the limit.
        # sqrt(Ti*Td) of a subnormal Td underflows to 0: that is a tracking time under dt too.
        tracking = self.tracking_time
        reset = 1.0 if tracking <= dt else dt / tracking
        self.integral += g.Kp * dt / g.Ti * e + reset * (u - demand)
        self.output = u
        return u

    def to_dict(self) -> dict[str, Any]:
        """Return the configuration and state (JSON-ready)."""
        return {
            **self._gains.to_dict(),
            "u_min": self.u_min,
            "u_max": self.u_max,
            "derivative_filter": self.derivative_filter,
            "tracking_time": self.tracking_time,
            "anti_windup": "back-calculation",
            "integral": self.integral,
            # Not jsonsafe.finite_or_none: that module loads NumPy, this one must not.
            "output": self.output if math.isfinite(self.output) else None,
        }
