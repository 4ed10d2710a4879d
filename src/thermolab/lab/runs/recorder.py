"""Where a run's samples go while it runs: the database, in batches, riding out outages.

:class:`DatabaseRecorder` is the runner's recorder for a lab run (the
sampling loop never waits on the database); :data:`STORE_GRACE` is how long a
run rides out a database that does not answer.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from sqlalchemy import insert, update
from sqlalchemy.exc import SQLAlchemyError

from thermolab.errors import ThermoLabError
from thermolab.jsonsafe import finite_or_none
from thermolab.lab.db import Database
from thermolab.lab.db.models import Run, Sample
from thermolab.records import RUN_CHANNELS, ChannelSpec

__all__ = ["STORE_GRACE", "DatabaseRecorder", "ride_out"]

log = logging.getLogger(__name__)

T = TypeVar("T")


STORE_GRACE = 30.0
"""Seconds a run rides out a database that does not answer (its samples kept in memory)."""


def ride_out(action: Callable[[], T], what: str, interval: float, grace: float = STORE_GRACE) -> T:
    """``action()``, tried again every ``interval`` s while the database fails, for ``grace`` s.

    The one way a run's storage outlasts an outage (its last samples, its end);
    the first failure is logged once, and the last one is raised.
    """
    began = time.monotonic()
    while True:
        try:
            return action()
        except SQLAlchemyError as exc:
            if time.monotonic() - began > grace:
                raise
            if time.monotonic() - began < interval:
                log.warning(
                    "%s failed (%s); trying again for %g s", what, type(exc).__name__, grace
                )
            time.sleep(interval)


class DatabaseRecorder:
    """A runner :class:`~thermolab.runner.Recorder` that stores samples in the database.

    ``write`` (called by the sampling loop) appends to a buffer under a lock;
    a writer thread inserts the buffer every ``interval`` seconds of real
    time; ``close`` inserts the rest before returning.

    A database that stops answering (a restart, a failover) does not cost the
    run: the samples stay in the buffer, in order, and the writer tries again
    every ``interval``; the run goes on. Only after ``grace`` seconds without a
    successful insert does ``write`` raise (the run ends, the rig made safe),
    and ``close`` keeps trying for as long before it gives up.

    Parameters
    ----------
    db : Database
    run_id : int
    interval : float
        Longest time (seconds) a sample waits in memory.
    on_sample : callable, optional
        Called with each sample's ``(u, y)`` (keeps the lab's view of the rig fresh).
    channels : sequence of ChannelSpec, optional
        The run's channels (``Experiment.channels``): :data:`~thermolab.records.RUN_CHANNELS`
        (the default), then any extra channels, whose values ``write`` takes
        after the standard ones.
    grace : float
        Seconds of failed inserts a run rides out (default :data:`STORE_GRACE`).
    """

    def __init__(
        self,
        db: Database,
        run_id: int,
        *,
        interval: float = 0.5,
        on_sample: Callable[[float, float], None] | None = None,
        channels: Sequence[ChannelSpec] = RUN_CHANNELS,
        grace: float = STORE_GRACE,
    ) -> None:
        # The standard channels by name: their units are the rig's (see run_channels).
        if [c.name for c in channels[: len(RUN_CHANNELS)]] != [c.name for c in RUN_CHANNELS]:
            raise ThermoLabError("a run's channels start with thermolab.records.RUN_CHANNELS")
        self.channels = tuple(channels)
        self._extra = tuple(c.name for c in channels[len(RUN_CHANNELS) :])
        self._db = db
        self.run_id = run_id
        self._interval = interval
        self._on_sample = on_sample
        self._buffer: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._flush_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.stored = 0
        self.error: BaseException | None = None
        self._grace = grace
        self._failing_since: float | None = None

    def open(self) -> None:
        """Start the writer thread."""
        self._thread = threading.Thread(
            target=self._loop, name=f"thermolab-run-{self.run_id}-writer", daemon=True
        )
        self._thread.start()

    def write(
        self,
        k: int,
        t: float,
        u: float,
        y: float,
        t_read: float,
        jitter: float,
        lateness: float,
        *extra: float,
    ) -> None:
        """Queue one sample, every channel, for the database (never blocks on it)."""
        if self.error is not None:
            # The store failed: stop the run rather than lose samples silently.
            raise ThermoLabError(f"cannot store the run's samples: {self.error}")
        row = {
            "run_id": self.run_id,
            "k": k,
            "t": t,
            "u": u,
            "y": y,
            "t_read": t_read,
            "jitter": jitter,
            "lateness": lateness,
            # JSON has no NaN (PostgreSQL refuses it): a missing value is null.
            "extra": {n: finite_or_none(v) for n, v in zip(self._extra, extra, strict=True)}
            if self._extra
            else None,
        }
        with self._lock:
            self._buffer.append(row)
        if self._on_sample is not None:
            self._on_sample(u, y)

    def flush(self) -> int:
        """Insert the buffered samples now; return how many.

        On failure the samples go back to the front of the buffer, in order, and
        the error is raised: nothing taken is dropped.
        """
        with self._flush_lock:
            with self._lock:
                rows, self._buffer = self._buffer, []
            if not rows:
                return 0
            try:
                with self._db.write() as session:
                    session.execute(insert(Sample), rows)
                    session.execute(
                        update(Run)
                        .where(Run.id == self.run_id)
                        .values(samples_stored=Run.samples_stored + len(rows))
                    )
            except BaseException:
                with self._lock:
                    self._buffer[:0] = rows
                raise
            self.stored += len(rows)
            return len(rows)

    def close(self) -> None:
        """Stop the writer and store what is left (idempotent; rides out ``grace``)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        ride_out(
            self.flush, f"run {self.run_id}: storing its last samples", self._interval, self._grace
        )

    def _loop(self) -> None:
        while not self._stop.wait(self._interval):
            try:
                self.flush()
            except Exception as exc:
                now = time.monotonic()
                if self._failing_since is None:
                    self._failing_since = now
                    log.warning(
                        "run %s: storing samples failed (%s); kept in memory, trying again "
                        "for %g s",
                        self.run_id,
                        str(exc).strip().splitlines()[0] if str(exc).strip() else exc,
                        self._grace,
                    )
                if now - self._failing_since > self._grace:
                    self.error = exc  # raised in the sampling loop by write()
                    log.exception("run %s: storing samples failed for too long", self.run_id)
                    return
                continue
            if self._failing_since is not None:
                log.warning(
                    "run %s: storing samples again after %.0f s",
                    self.run_id,
                    time.monotonic() - self._failing_since,
                )
                self._failing_since = None
