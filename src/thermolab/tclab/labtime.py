"""Lab time and the sampling clock, as the ``tclab`` package's ``labtime`` and ``clock``.

Lab time runs at a rate: 1 for a real rig, the twin's own speed-up for a
simulated rig (its teacher's setting, set when a :class:`~thermolab.tclab.TCLab`
connects), so a
notebook's ``for t in clock(600)`` takes 600 s on a kit and 12 s on a twin
the lab runs at 50×.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

__all__ = ["LabTime", "clock", "labtime"]


class LabTime:
    """A clock that runs ``rate`` times faster than real time (and may be paused).

    Examples
    --------
    >>> fast = LabTime()
    >>> fast.set_rate(1000.0)
    >>> start = fast.time(); fast.sleep(5.0); 4.9 < fast.time() - start < 60.0
    True
    """

    def __init__(self) -> None:
        self._rate = 1.0
        self._real0 = time.monotonic()
        self._lab0 = 0.0
        self._running = True

    @property
    def rate(self) -> float:
        """Lab seconds per real second."""
        return self._rate

    @property
    def running(self) -> bool:
        """Whether lab time is moving."""
        return self._running

    def time(self) -> float:
        """Lab time in seconds."""
        if not self._running:
            return self._lab0
        return self._lab0 + self._rate * (time.monotonic() - self._real0)

    def set_rate(self, rate: float = 1.0) -> None:
        """Run ``rate`` times faster than real time from now on (lab time stays continuous).

        Raises
        ------
        ValueError
            Unless ``rate`` is a positive finite number.
        """
        if not (isinstance(rate, int | float) and math.isfinite(rate) and rate > 0):
            raise ValueError(f"labtime's rate must be a positive finite number; got {rate!r}")
        self._lab0, self._real0 = self.time(), time.monotonic()
        self._rate = float(rate)

    def sleep(self, delay: float) -> None:
        """Sleep ``delay`` lab seconds."""
        if delay > 0:
            time.sleep(delay / self._rate)

    def stop(self) -> None:
        """Pause lab time."""
        self._lab0, self._running = self.time(), False

    def start(self) -> None:
        """Let lab time move again."""
        self._real0, self._running = time.monotonic(), True

    def reset(self, t: float = 0.0) -> None:
        """Set lab time to ``t``."""
        self._lab0, self._real0 = float(t), time.monotonic()


labtime = LabTime()
"""The module's lab time (``tclab.labtime``), shared by :func:`clock` and the historian."""


def clock(
    period: float, step: float = 1.0, tol: float = math.inf, adaptive: bool = True
) -> Iterator[float]:
    """Yield the lab time since the start, every ``step`` lab seconds, up to ``period``.

    Parameters
    ----------
    period : float
        Lab seconds to run (the last value yielded is at most ``period``).
    step : float
        Lab seconds between values.
    tol : float
        Lab seconds a step may start late before ``RuntimeError`` (default: any).
    adaptive : bool
        Sleep to the next multiple of ``step`` (no drift; steps missed by a slow
        body are skipped, so the loop still ends at ``period``); ``False``
        sleeps ``step`` after each body, whatever it took.

    Raises
    ------
    ValueError
        For a step that is not positive.
    RuntimeError
        When a step starts more than ``tol`` late (the loop's body is too slow).
    """
    if not step > 0:
        raise ValueError(f"clock's step must be positive; got {step!r}")
    start = labtime.time()
    k = 0
    while True:
        yield round(labtime.time() - start, 2)
        k += 1
        now = labtime.time() - start
        if now > k * step + tol:
            raise RuntimeError(
                f"clock: step {k} is {now - k * step:.2f} s late (tol = {tol} s); "
                "the loop's body takes longer than the step"
            )
        if adaptive:
            k = max(k, math.floor(now / step + 1e-9) + 1)  # skip the steps already missed
        if k * step > period + 1e-9 or (not adaptive and now + step > period + 1e-9):
            return
        labtime.sleep(k * step - now if adaptive else step)
