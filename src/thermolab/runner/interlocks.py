"""Safety interlocks of a run: output limits, input range, and a watchdog.

The rig has its own protections (:class:`~thermolab.rigs.BaseRig` faults
above ``RigInfo.output_limit`` and refuses inputs outside its range); the
runner adds the ones that belong to an experiment:

* an output window for this run (``output_max`` — over-temperature — and
  ``output_min`` — a sensor that has come loose reads far below ambient),
  and a reading that is not a finite number;
* a range check of every input before it reaches the rig (a signal or set
  point outside the rig's range stops the run rather than being clipped
  silently);
* a watchdog: a thread that puts the rig at its safe value when the sampling
  loop makes no progress for ``watchdog`` seconds of wall-clock time (an
  identifier or a recorder that hangs, a starved process). Time spent
  waiting for the next deadline does not count. A stall *inside* a rig call
  is the rig's own business: its I/O has a timeout and raises
  :class:`~thermolab.errors.RigTimeoutError`.

When an interlock trips the run puts the actuator at the safe input, publishes
a fault event and ends FAULTED.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from thermolab.errors import InvalidParameterError
from thermolab.rigs import RigInfo

__all__ = ["Interlocks", "Watchdog"]


def _check_optional_finite(name: str, value: float | None) -> None:
    if value is not None and not (isinstance(value, int | float) and math.isfinite(value)):
        raise InvalidParameterError(f"{name} must be a finite number or None, got {value!r}")


@dataclass(frozen=True, slots=True)
class Interlocks:
    """The interlocks of one run.

    Parameters
    ----------
    output_max : float or None, optional
        The run faults when a reading exceeds it (over-temperature), in the
        rig's output unit. ``None``: only the rig's own limit applies.
    output_min : float or None, optional
        The run faults when a reading falls below it. ``None``: no lower limit.
    watchdog : float or None, optional
        Wall-clock seconds without progress of the sampling loop before the
        rig is made safe and the run faults (default 10 s, long enough for a
        first-call compilation of the numerical kernels). ``None`` disables it.

    Raises
    ------
    InvalidParameterError
        If a limit is not finite, ``output_min >= output_max`` or the watchdog
        timeout is not positive.

    Examples
    --------
    >>> locks = Interlocks(output_max=80.0)
    >>> locks.check_output(25.0, "degC") is None
    True
    >>> locks.check_output(81.5, "degC")
    'output 81.5 degC is above the limit of 80 degC'
    """

    output_max: float | None = None
    output_min: float | None = None
    watchdog: float | None = 10.0

    def __post_init__(self) -> None:
        _check_optional_finite("output_max", self.output_max)
        _check_optional_finite("output_min", self.output_min)
        if (
            self.output_max is not None
            and self.output_min is not None
            and not self.output_min < self.output_max
        ):
            raise InvalidParameterError(
                f"output_min ({self.output_min}) must be below output_max ({self.output_max})"
            )
        if self.watchdog is not None and not (
            isinstance(self.watchdog, int | float)
            and math.isfinite(self.watchdog)
            and self.watchdog > 0
        ):
            raise InvalidParameterError(
                f"watchdog must be a positive number of seconds or None, got {self.watchdog!r}"
            )

    def check_output(self, y: float, unit: str = "") -> str | None:
        """Return why a reading must stop the run, or ``None`` if it is fine.

        Parameters
        ----------
        y : float
            The reading.
        unit : str, optional
            The output unit, for the message.

        Returns
        -------
        str or None
            One line naming the reading and the limit it broke.
        """
        unit = f" {unit}" if unit else ""
        if not math.isfinite(y):
            return f"the sensor returned {y!r}, not a number"
        if self.output_max is not None and y > self.output_max:
            return f"output {y:g}{unit} is above the limit of {self.output_max:g}{unit}"
        if self.output_min is not None and y < self.output_min:
            return f"output {y:g}{unit} is below the limit of {self.output_min:g}{unit}"
        return None

    @staticmethod
    def check_input(u: float, info: RigInfo) -> str | None:
        """Return why an input must not be applied, or ``None`` if it is in range.

        Parameters
        ----------
        u : float
            The input about to be applied.
        info : RigInfo
            The rig's description (its input range and unit).

        Returns
        -------
        str or None
            One line naming the input and the allowed range.

        Examples
        --------
        >>> info = RigInfo("demo", "twin", -10.0, 10.0, "V", "V", 0.0, None)
        >>> Interlocks.check_input(12.0, info)
        "input 12 V is outside the range of 'demo': [-10, 10] V"
        """
        if math.isfinite(u) and info.input_min <= u <= info.input_max:
            return None
        return (
            f"input {u:g} {info.input_unit} is outside the range of {info.name!r}: "
            f"[{info.input_min:g}, {info.input_max:g}] {info.input_unit}"
        )


class Watchdog:
    """Calls ``on_trip`` once if the loop it watches stops beating.

    The watched loop calls :meth:`beat` as it makes progress and brackets
    intended waits with :meth:`pause` / :meth:`resume`. A daemon thread checks
    the time since the last beat against ``timeout`` (wall-clock seconds).

    Parameters
    ----------
    timeout : float
        Seconds without a beat (outside pauses) before tripping.
    on_trip : callable
        Called once, on the watchdog's thread, with the seconds since the last
        beat. It must make the rig safe and must not raise.
    wall : callable, optional
        The wall clock (default :func:`time.monotonic`).

    Examples
    --------
    >>> tripped = []
    >>> dog = Watchdog(0.05, tripped.append)
    >>> dog.start()
    >>> _ = dog.wait_tripped(5.0)
    >>> dog.stop()
    >>> dog.tripped, tripped[0] >= 0.05
    (True, True)
    """

    def __init__(
        self,
        timeout: float,
        on_trip: Callable[[float], object],
        *,
        wall: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (math.isfinite(timeout) and timeout > 0):
            raise InvalidParameterError(
                f"watchdog timeout must be a positive number of seconds, got {timeout!r}"
            )
        self.timeout = float(timeout)
        self._on_trip = on_trip
        self._wall = wall
        self._last = wall()
        self._paused = False
        self._stop = threading.Event()
        self._tripped = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="thermolab-watchdog", daemon=True)

    @property
    def tripped(self) -> bool:
        """``True`` once the watchdog has fired."""
        return self._tripped.is_set()

    def start(self) -> None:
        """Start watching (the first beat is now)."""
        self._last = self._wall()
        self._thread.start()

    def beat(self) -> None:
        """Record progress."""
        self._last = self._wall()

    def pause(self) -> None:
        """An intended wait begins: it does not count as a stall."""
        self._paused = True

    def resume(self) -> None:
        """The intended wait is over (counts as a beat)."""
        self._last = self._wall()
        self._paused = False

    def stop(self) -> None:
        """Stop watching (idempotent)."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join()

    def wait_tripped(self, timeout: float | None = None) -> bool:
        """Block until the watchdog fires or ``timeout`` passes; return :attr:`tripped`."""
        return self._tripped.wait(timeout)

    def _watch(self) -> None:
        poll = min(self.timeout / 4.0, 0.25)
        while not self._stop.wait(poll):
            if self._paused:
                continue
            stalled = self._wall() - self._last
            if stalled > self.timeout and not self._paused:
                self._tripped.set()
                self._on_trip(stalled)
                return
