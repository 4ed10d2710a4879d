"""Clocks: the one source of time for rigs and the experiment runner.

Every rig and the runner take a :class:`Clock` instead of calling :mod:`time`,
so the same code runs in real time (the lab), in virtual time as fast as
possible (tests, batch runs), in virtual time that runs a fixed number of
times faster than real time (a demonstration of a 2000 s experiment in 20 s),
or at a rate that can be changed while time stays continuous (a lab's twin,
whose speed-up a teacher sets: :class:`RateClock`).

Times are seconds as ``float``; only differences matter (the origin is
arbitrary, as with :func:`time.monotonic`).
"""

from __future__ import annotations

import math
import threading
import time
from typing import Protocol, runtime_checkable

from thermolab.errors import InvalidParameterError

__all__ = ["Clock", "RateClock", "RealClock", "ScaledClock", "VirtualClock", "make_clock"]


@runtime_checkable
class Clock(Protocol):
    """A source of monotonic time that can wait until a given instant.

    Notes
    -----
    ``sleep_until(t)`` returns at or after ``t`` (never before); when ``t`` is
    already past it returns at once. Implementations are thread-safe.
    """

    def now(self) -> float:
        """Return the current time in seconds."""
        ...

    def sleep_until(self, t: float) -> None:
        """Block until the clock reads at least ``t``."""
        ...


class RealClock:
    """Wall-clock time from :func:`time.monotonic` (never jumps, never goes back).

    Examples
    --------
    >>> clock = RealClock()
    >>> t0 = clock.now()
    >>> clock.sleep_until(t0)  # already reached: returns at once
    >>> clock.now() >= t0
    True
    """

    def now(self) -> float:
        """Return :func:`time.monotonic`."""
        return time.monotonic()

    def sleep_until(self, t: float) -> None:
        """Sleep until :func:`time.monotonic` reaches ``t``.

        Parameters
        ----------
        t : float
            Target instant on this clock.
        """
        # time.sleep may wake early on some platforms; loop until the instant has passed.
        while True:
            remaining = t - time.monotonic()
            if remaining <= 0.0:
                return
            time.sleep(remaining)

    def __repr__(self) -> str:
        return "RealClock()"


class VirtualClock:
    """Virtual time that advances instantly: experiments run as fast as possible.

    ``sleep_until(t)`` moves the clock to ``t`` and returns at once. Time never
    goes back: sleeping until a past instant leaves the clock where it is.

    Parameters
    ----------
    start : float, optional
        The initial reading (default 0.0).

    Examples
    --------
    >>> clock = VirtualClock()
    >>> clock.sleep_until(2000.0)
    >>> clock.now()
    2000.0
    >>> clock.advance(0.5)
    >>> clock.now()
    2000.5
    """

    def __init__(self, start: float = 0.0) -> None:
        if not math.isfinite(start):
            raise InvalidParameterError(f"clock start must be a finite number, got {start!r}")
        self._t = float(start)
        self._lock = threading.Lock()

    def now(self) -> float:
        """Return the current virtual time."""
        with self._lock:
            return self._t

    def sleep_until(self, t: float) -> None:
        """Advance the clock to ``t`` at once (no effect if ``t`` is already past).

        Parameters
        ----------
        t : float
            Target instant.

        Raises
        ------
        InvalidParameterError
            If ``t`` is NaN or infinite.
        """
        if not math.isfinite(t):
            raise InvalidParameterError(f"sleep_until needs a finite instant, got {t!r}")
        with self._lock:
            self._t = max(self._t, float(t))

    def advance(self, dt: float) -> None:
        """Move the clock forward by ``dt`` seconds.

        Parameters
        ----------
        dt : float
            A finite, non-negative duration.

        Raises
        ------
        InvalidParameterError
            If ``dt`` is negative or not finite.
        """
        if not (math.isfinite(dt) and dt >= 0.0):
            raise InvalidParameterError(
                f"a clock can only advance by a finite duration >= 0, got {dt!r}"
            )
        with self._lock:
            self._t += float(dt)

    def __repr__(self) -> str:
        return f"VirtualClock(start={self.now()!r})"


class RateClock:
    """Virtual time running ``rate`` times a source clock, with a rate that can change.

    A change of rate (:meth:`set_rate`) keeps the time continuous: the clock
    reads the same just before and just after, and from then on advances at
    the new rate; it never jumps and never goes back. A :meth:`sleep_until`
    in progress waits on its source in slices of at most ``max_slice`` source
    seconds and recomputes its end after each one, so it honours a new rate
    within a slice. A lab gives each twin its own (the teacher's
    ``twin_speedup``; :mod:`thermolab.lab.rigs.devices`).

    Parameters
    ----------
    rate : float
        Positive, finite factor: virtual seconds per source second.
    source : Clock, optional
        The clock that really passes (default :class:`RealClock`).
    start : float, optional
        The virtual time at construction (default 0.0).
    max_slice : float, optional
        Longest wait on the source before a sleep looks at the rate again
        (default 0.05 s; ``math.inf`` for a rate nobody changes).

    Raises
    ------
    InvalidParameterError
        If ``rate`` or ``start`` is not a finite number, or ``rate`` or
        ``max_slice`` is not positive.

    Examples
    --------
    >>> source = VirtualClock()
    >>> clock = RateClock(10.0, source=source)
    >>> source.advance(2.0)
    >>> clock.now()
    20.0
    >>> clock.set_rate(100.0)  # the time goes on from 20 s, 100 times the source
    >>> source.advance(1.0)
    >>> clock.now()
    120.0
    """

    def __init__(
        self,
        rate: float,
        *,
        source: Clock | None = None,
        start: float = 0.0,
        max_slice: float = 0.05,
    ) -> None:
        self._check_rate(rate)
        if not math.isfinite(start):
            raise InvalidParameterError(f"clock start must be a finite number, got {start!r}")
        if not max_slice > 0.0:  # math.inf: one wait per sleep (a fixed rate)
            raise InvalidParameterError(
                f"max_slice must be a positive number of seconds, got {max_slice!r}"
            )
        self._lock = threading.Lock()
        self._source: Clock = source if source is not None else RealClock()
        self._rate = float(rate)
        self._max_slice = float(max_slice)
        # now() = _at + _rate * (source.now() - _source_at): re-anchored at every change.
        self._source_at = self._source.now()
        self._at = float(start)

    @staticmethod
    def _check_rate(rate: float) -> None:
        if isinstance(rate, bool) or not (math.isfinite(rate) and rate > 0.0):
            raise InvalidParameterError(
                f"a clock rate must be a positive finite number, got {rate!r}"
            )

    @property
    def rate(self) -> float:
        """Virtual seconds per source second, now."""
        with self._lock:
            return self._rate

    def _now(self) -> float:
        # Float rounding is monotonic, so this never decreases while the source does not.
        return self._at + self._rate * (self._source.now() - self._source_at)

    def now(self) -> float:
        """Return the virtual time."""
        with self._lock:
            return self._now()

    def set_rate(self, rate: float) -> None:
        """Run at ``rate`` from now on; the time reads on from where it is.

        Raises
        ------
        InvalidParameterError
            If ``rate`` is not a positive finite number.
        """
        self._check_rate(rate)
        with self._lock:
            source_now = self._source.now()
            self._at = self._at + self._rate * (source_now - self._source_at)
            self._source_at = source_now
            self._rate = float(rate)

    def sleep_until(self, t: float) -> None:
        """Wait on the source until the virtual time reaches ``t``, at the rate in force.

        Parameters
        ----------
        t : float
            Target virtual instant.
        """
        if not math.isfinite(t):
            raise InvalidParameterError(f"sleep_until needs a finite instant, got {t!r}")
        while True:
            with self._lock:
                source_now = self._source.now()
                if self._at + self._rate * (source_now - self._source_at) >= t:
                    return
                target = self._source_at + (t - self._at) / self._rate
                wake = min(target, source_now + self._max_slice)
                if wake <= source_now:
                    # Rounding left now() a hair short of t: wait out the last ulp.
                    wake = math.nextafter(source_now, math.inf)
            self._source.sleep_until(wake)

    def __repr__(self) -> str:
        return f"RateClock({self.rate!r}, source={self._source!r})"


class ScaledClock(RateClock):
    """Virtual time that runs ``speedup`` times faster than a source clock: a :class:`RateClock`
    whose rate the program that made it does not change.

    With ``speedup=100`` a 2000 s experiment takes 20 s of real time, and the
    runner's schedule, the rig's physics and every timestamp agree on the
    virtual time.

    Parameters
    ----------
    speedup : float
        Positive, finite factor: virtual seconds per source second.
    source : Clock, optional
        The clock that really passes (default :class:`RealClock`). Tests pass a
        :class:`VirtualClock` here so that nothing sleeps.
    start : float, optional
        The virtual time at construction (default 0.0).

    Raises
    ------
    InvalidParameterError
        If ``speedup`` is not a positive finite number.

    Examples
    --------
    >>> source = VirtualClock()
    >>> clock = ScaledClock(10.0, source=source)
    >>> source.advance(2.0)
    >>> clock.now()
    20.0
    >>> clock.sleep_until(50.0)  # waits 3 s on the source
    >>> source.now()
    5.0
    """

    def __init__(self, speedup: float, *, source: Clock | None = None, start: float = 0.0) -> None:
        if not (math.isfinite(speedup) and speedup > 0.0):
            raise InvalidParameterError(
                f"speed-up must be a positive finite number, got {speedup!r} "
                "(use VirtualClock for 'as fast as possible')"
            )
        # One wait on the source per sleep: nothing changes the rate to look at between.
        super().__init__(speedup, source=source, start=start, max_slice=math.inf)

    @property
    def speedup(self) -> float:
        """Virtual seconds per source second."""
        return self.rate

    def __repr__(self) -> str:
        return f"ScaledClock({self.speedup!r}, source={self._source!r})"


def make_clock(speedup: float | None = 1.0) -> Clock:
    """Return the clock for a requested speed-up.

    Parameters
    ----------
    speedup : float or None
        ``1`` (default) or ``None``: real time; ``math.inf``: virtual time as
        fast as possible; any other positive factor: virtual time running that
        many times faster than real time.

    Returns
    -------
    Clock
        :class:`RealClock`, :class:`VirtualClock` or :class:`ScaledClock`.

    Raises
    ------
    InvalidParameterError
        If ``speedup`` is zero, negative or NaN.

    Examples
    --------
    >>> make_clock(math.inf)
    VirtualClock(start=0.0)
    >>> make_clock(None)
    RealClock()
    """
    if speedup is None or speedup == 1.0:
        return RealClock()
    if speedup == math.inf:
        return VirtualClock()
    if not (math.isfinite(speedup) and speedup > 0.0):
        raise InvalidParameterError(
            f"speed-up must be a positive number or inf (as fast as possible), got {speedup!r}"
        )
    return ScaledClock(speedup)
