"""Lab time and the sampling clock, as the ``tclab`` package's ``labtime``, ``clock``, ``setnow``.

Lab time runs at a rate: 1 for a real rig; for the offline
:class:`~thermolab.tclab.TCLabModel` the ``speedup`` given to
:func:`~thermolab.tclab.setup`; for a lab's twin the twin's own speed-up (its
teacher's setting), which the lab imposes when a
:class:`~thermolab.tclab.TCLab` connects — the rate is then *held* by that
rig until it closes, because the twin's clock is the lab's and a client
cannot slow it down or speed it up.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Iterator

__all__ = ["LabTime", "LabTimeStoppedError", "clock", "labtime", "setnow"]


class LabTimeStoppedError(RuntimeWarning):
    """``labtime.sleep`` while lab time is stopped (the ``tclab`` package raises RuntimeWarning)."""


class LabTime:
    """A clock that runs ``rate`` times faster than real time (and may be stopped).

    Examples
    --------
    >>> fast = LabTime()
    >>> fast.set_rate(1000.0)
    >>> start = fast.time(); fast.sleep(5.0); fast.time() - start >= 4.9  # 5 ms of real time
    True
    >>> fast.get_rate()
    1000.0
    """

    def __init__(self) -> None:
        self._rate = 1.0
        self._real0 = time.monotonic()
        self._lab0 = 0.0
        self._running = True
        self._holder: str | None = None
        self.lastsleep = 0.0
        """The last delay given to :meth:`sleep`, in lab seconds."""

    @property
    def rate(self) -> float:
        """Lab seconds per real second."""
        return self._rate

    @property
    def running(self) -> bool:
        """Whether lab time is moving."""
        return self._running

    @property
    def held_by(self) -> str | None:
        """Who imposes the rate (a lab's twin, named), or ``None`` when the notebook chooses it."""
        return self._holder

    def time(self) -> float:
        """Lab time in seconds."""
        if not self._running:
            return self._lab0
        return self._lab0 + self._rate * (time.monotonic() - self._real0)

    def get_rate(self) -> float:
        """Lab seconds per real second (the ``tclab`` package's name for :attr:`rate`)."""
        return self._rate

    def set_rate(self, rate: float = 1) -> None:
        """Run ``rate`` times faster than real time from now on (lab time stays continuous).

        Raises
        ------
        ValueError
            Unless ``rate`` is a positive finite number, or when a lab's twin
            holds the rate and ``rate`` is another.
        """
        if not (isinstance(rate, int | float) and math.isfinite(rate) and rate > 0):
            raise ValueError(f"labtime's rate must be a positive finite number; got {rate!r}")
        if self._holder is not None and float(rate) != self._rate:
            raise ValueError(
                f"labtime runs at {self._rate:g}x because {self._holder}; a client cannot "
                f"change it to {rate:g}x (close that TCLab first)"
            )
        self._lab0, self._real0 = self.time(), time.monotonic()
        self._rate = float(rate)

    def hold(self, rate: float, holder: str | None) -> None:
        """Impose ``rate`` for ``holder`` (a connected lab twin); ``holder=None`` lets go."""
        self._holder = None
        if holder is not None:
            self.set_rate(rate)
            self._holder = holder

    def sleep(self, delay: float) -> None:
        """Sleep ``delay`` lab seconds.

        Raises
        ------
        LabTimeStoppedError
            While lab time is stopped (it would never end).
        """
        self.lastsleep = delay
        if not self._running:
            raise LabTimeStoppedError(
                "labtime.sleep while labtime is stopped would never end: labtime.start() first"
            )
        if delay > 0:
            time.sleep(delay / self._rate)

    def stop(self) -> None:
        """Stop lab time."""
        self._lab0, self._real0, self._running = self.time(), time.monotonic(), False

    def start(self) -> None:
        """Let lab time move again."""
        self._real0, self._running = time.monotonic(), True

    def reset(self, val: float = 0) -> None:
        """Set lab time to ``val`` seconds."""
        self._lab0, self._real0 = float(val), time.monotonic()


labtime = LabTime()
"""The module's lab time (``tclab.labtime``), shared by :func:`clock`, the historian and models."""


def setnow(tnow: float = 0) -> None:
    """Set lab time to ``tnow`` seconds (the ``tclab`` package's older name for ``reset``)."""
    labtime.reset(tnow)


def _late_note(late: float, step: float) -> str:
    return (
        f"note: clock's step {step:g} s came {late:.2f} lab s late: {labtime.held_by}, and "
        "the lab cannot slow the twin down for the loop the way TCLabModel's adaptive clock "
        "slows its lab time, so late steps are taken at once (none skipped; the times are the "
        "twin's). A slower loop body needs a larger step or a twin with a lower speed-up"
    )


def clock(
    period: float, step: float = 1, tol: float = math.inf, adaptive: bool = True
) -> Iterator[float]:
    """Yield lab seconds since the start, every ``step``, until ``period`` (as ``tclab.clock``).

    Parameters
    ----------
    period : float
        Lab seconds to run; the last value is ``period`` (rounded to a second)
        when the loop keeps up.
    step : float
        Lab seconds between values.
    tol : float
        Lab seconds a step may start late beyond ``step`` before
        ``RuntimeError`` (default: any). Not checked while ``adaptive`` adapts
        the rate, as in the ``tclab`` package.
    adaptive : bool
        When lab time runs faster than real time (``rate != 1``): the
        ``tclab`` package's meaning — lab time slows down (to 80 % of the pace
        the loop's body allows) when a step overruns and speeds up (by 25 %,
        while under 50x) when the body takes under half a step, so no step is lost.
        On a lab twin, whose rate the lab holds, the rate cannot change: a
        late step is then taken at once, none is skipped (the loop logs every
        step, at the twin's times), and a note says so once. At ``rate == 1``
        or with ``adaptive=False``: sleep to the next multiple of ``step``
        (steps missed by a slow body are skipped) and check ``tol``.

    Yields
    ------
    float
        Lab seconds since the loop began, rounded to 0.01 s.

    Raises
    ------
    ValueError
        For a step that is not positive.
    RuntimeError
        When a step starts more than ``step + tol`` after the previous one.
    """
    if not step > 0:
        raise ValueError(f"clock's step must be positive; got {step!r}")
    start = labtime.time()
    if labtime.get_rate() != 1 and adaptive and labtime.held_by is not None:
        yield from _held_clock(start, period, step)
        return
    now = 0.0
    k = 0  # the step yielded last
    while round(now) <= period:
        yield round(now, 2)
        if round(now) >= period:
            return
        elapsed = labtime.time() - (start + now)
        rate = labtime.get_rate()
        if rate != 1 and adaptive:
            if elapsed > step:
                labtime.set_rate(0.8 * rate * step / elapsed)
            elif elapsed < 0.5 * step and rate < 50:
                labtime.set_rate(1.25 * rate)
        elif elapsed > step + tol:
            raise RuntimeError(
                f"clock lost synchronisation with real time: the step is {step:g} s but "
                f"{elapsed:.2f} s passed ({elapsed - step:.2f} s more; tol = {tol:g} s). "
                "Make the step larger or the loop's body faster"
            )
        # To the next multiple of step (skipping those missed), and never the same one twice:
        # a sleep that wakes a hair early would otherwise yield one time twice (tclab does).
        k = max(k + 1, math.floor((labtime.time() - start) / step + 1e-9) + 1)
        while (now := labtime.time() - start) < k * step:
            labtime.sleep(k * step - now)


def _held_clock(start: float, period: float, step: float) -> Iterator[float]:
    # A lab twin's rate cannot adapt: every step is yielded, a late one at once.
    k = 0
    warned = False
    while True:
        yield round(labtime.time() - start, 2) if k else 0.0
        k += 1
        if k * step > period + 1e-9:
            return
        late = labtime.time() - start - k * step
        if late > step and not warned:
            print(_late_note(late, step), file=sys.stderr)
            warned = True
        while late < 0:  # a timer may wake a hair early: the step's time is not yet there
            labtime.sleep(-late)
            late = labtime.time() - start - k * step
