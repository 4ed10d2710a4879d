"""Wall-clock time for the lab service, injected so that tests never sleep.

The lab measures human-scale time (a 300 s control limit, a client silent for
15 s, a session that expires) and stores instants in the database, so its
clock gives timezone-aware UTC :class:`~datetime.datetime` values rather than
the monotonic seconds of :mod:`thermolab.rigs.clock` (which drive the physics
of a rig). :class:`ManualClock` stands still until a test moves it.
"""

from __future__ import annotations

import threading
from datetime import UTC, datetime, timedelta
from typing import Protocol, runtime_checkable

from thermolab.errors import InvalidParameterError

__all__ = ["LabClock", "ManualClock", "SystemClock"]


@runtime_checkable
class LabClock(Protocol):
    """A source of the current instant (timezone-aware, UTC)."""

    def now(self) -> datetime:
        """Return the current instant."""
        ...


class SystemClock:
    """The real time of day, in UTC.

    Examples
    --------
    >>> SystemClock().now().tzinfo is UTC
    True
    """

    def now(self) -> datetime:
        """Return :func:`datetime.now` in UTC."""
        return datetime.now(UTC)

    def __repr__(self) -> str:
        return "SystemClock()"


class ManualClock:
    """A clock that only moves when told to (tests, simulations of a class).

    Parameters
    ----------
    start : datetime, optional
        The first instant (default 2026-01-01 00:00 UTC); must be timezone-aware.

    Raises
    ------
    InvalidParameterError
        If ``start`` is naive.

    Examples
    --------
    >>> clock = ManualClock()
    >>> t0 = clock.now()
    >>> clock.advance(15.5)
    >>> (clock.now() - t0).total_seconds()
    15.5
    """

    def __init__(self, start: datetime | None = None) -> None:
        if start is None:
            start = datetime(2026, 1, 1, tzinfo=UTC)
        if start.tzinfo is None:
            raise InvalidParameterError("ManualClock needs a timezone-aware start instant")
        self._now = start.astimezone(UTC)
        self._lock = threading.Lock()

    def now(self) -> datetime:
        """Return the current (manual) instant."""
        with self._lock:
            return self._now

    def advance(self, seconds: float) -> None:
        """Move the clock forward.

        Parameters
        ----------
        seconds : float
            How far, in seconds; must be finite and not negative.

        Raises
        ------
        InvalidParameterError
            If ``seconds`` is negative or not finite.
        """
        if not (seconds >= 0.0 and seconds != float("inf")):
            raise InvalidParameterError(
                f"a clock only moves forward by a finite amount, got {seconds!r} s"
            )
        with self._lock:
            self._now += timedelta(seconds=seconds)

    def __repr__(self) -> str:
        return f"ManualClock({self._now.isoformat()})"
