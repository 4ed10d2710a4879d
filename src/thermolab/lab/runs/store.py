"""Where runs are kept: samples as they come, results at the end, and reading them back.

Every sample goes to the ``samples`` table through :class:`DatabaseRecorder`,
which the runner calls once per sample; it only appends to a buffer, and a
writer thread inserts the buffer at least once a second, so a crash of the
server loses at most about a second of samples. At the end the methods'
results (final estimate, trajectories and statistics) go to
``method_results`` and the run row records how it ended
(:meth:`RunStore.save_end`).

A sample keeps every channel of the run (:data:`thermolab.records.RUN_CHANNELS`
and the extra channels a rig or controller adds, see
:class:`~thermolab.lab.db.models.Sample`); :meth:`RunStore.channels` and
:meth:`RunStore.channel_rows` read them back by name, and the CSV export
(:func:`samples_csv`) writes them with :mod:`thermolab.records`, the one
record format.
"""

from __future__ import annotations

import io
import logging
import math
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from sqlalchemy import func, insert, select, update
from sqlalchemy.orm import Session

from thermolab.errors import AccessDeniedError, NotFoundError, ThermoLabError
from thermolab.jsonsafe import finite_or_none, json_safe
from thermolab.lab.db import Database
from thermolab.lab.db.models import (
    Command,
    ControlSession,
    MethodResultRow,
    Run,
    RunStatus,
    Sample,
    User,
)
from thermolab.lab.security import normalize_username
from thermolab.lab.users import Principal
from thermolab.records import RUN_CHANNELS, ChannelSpec, RecordWriter
from thermolab.runner import EndReason

__all__ = [
    "DatabaseRecorder",
    "RunRecord",
    "RunStore",
    "StoredSample",
    "run_command",
    "samples_csv",
    "status_of",
]

log = logging.getLogger(__name__)

StoredSample = tuple[int, float, float, float]
"""``(k, t, u, y)`` of a stored sample."""

#: The channels of a sample stored before revision 0004 (no timing, no extras).
_EARLY_CHANNELS: tuple[ChannelSpec, ...] = RUN_CHANNELS[:4]
#: The standard channels, each a column of ``samples``.
_COLUMNS = {c.name: getattr(Sample, c.name) for c in RUN_CHANNELS}


@dataclass(frozen=True, slots=True)
class RunRecord:
    """A run as stored, with its live progress when it is running.

    ``results`` maps each method to its latest estimate (a JSON-ready dict,
    ``None`` before the first), why it stopped if it did (``error``) and, once
    the run is over, its statistics (``stats``, see :func:`method_statistics`).
    ``operating_point`` is :meth:`OperatingPoint.to_dict` of the run (``None``
    for runs stored before the lab recorded it). ``ends_at`` is the run's planned
    end (START time plus its length in real time; ``None`` for older runs).
    ``timing`` is how well the run kept its sampling times, from its end
    (:func:`thermolab.lab.runs.timing.timing_summary`; ``None`` before).
    """

    id: int
    rig_id: str
    username: str
    user_id: int
    status: str
    dt: float
    samples: int | None
    samples_stored: int
    samples_taken: int
    signal: str | None
    setpoint: float | None
    methods: list[str]
    settings: dict[str, Any]
    started_at: datetime
    ended_at: datetime | None
    end_reason: str | None
    results: dict[str, Any] = field(default_factory=dict)
    operating_point: dict[str, Any] | None = None
    ends_at: datetime | None = None
    timing: dict[str, Any] | None = None
    # A closed-loop run's controller: the loop's state (mode, set point, gains,
    # adaptive), live while it runs, as it ended afterwards; None for an open loop.
    control: dict[str, Any] | None = None


class DatabaseRecorder:
    """A runner :class:`~thermolab.runner.Recorder` that stores samples in the database.

    ``write`` (called by the sampling loop) appends to a buffer under a lock;
    a writer thread inserts the buffer every ``interval`` seconds of real
    time; ``close`` inserts the rest before returning.

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
    """

    def __init__(
        self,
        db: Database,
        run_id: int,
        *,
        interval: float = 0.5,
        on_sample: Callable[[float, float], None] | None = None,
        channels: Sequence[ChannelSpec] = RUN_CHANNELS,
    ) -> None:
        if tuple(channels[: len(RUN_CHANNELS)]) != RUN_CHANNELS:
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
        """Insert the buffered samples now; return how many."""
        with self._flush_lock:
            with self._lock:
                rows, self._buffer = self._buffer, []
            if not rows:
                return 0
            with self._db.write() as session:
                session.execute(insert(Sample), rows)
                session.execute(
                    update(Run)
                    .where(Run.id == self.run_id)
                    .values(samples_stored=Run.samples_stored + len(rows))
                )
            self.stored += len(rows)
            return len(rows)

    def close(self) -> None:
        """Stop the writer and store what is left (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self.flush()

    def _loop(self) -> None:
        while not self._stop.wait(self._interval):
            try:
                self.flush()
            except Exception as exc:  # kept, and raised in the sampling loop by write()
                self.error = exc
                log.exception("run %s: storing samples failed", self.run_id)
                return


def samples_csv(channels: Sequence[ChannelSpec], rows: Iterable[Sequence[float]]) -> Iterator[str]:
    r"""The CSV text of a run's record, in chunks, in the one record format.

    Written by :class:`thermolab.records.RecordWriter`.

    Columns ``t,u,y`` first, then the other channels: the file feeds straight
    into ``thermolab identify`` and :func:`thermolab.records.read_record`.

    Examples
    --------
    >>> from thermolab.records import RUN_CHANNELS
    >>> "".join(samples_csv(RUN_CHANNELS[:4], [(0.0, 1.0, 0.5, 0), (1.0, 1.0, 0.625, 1)]))
    't,u,y,k\n0,1.0,0.5,0\n1,1.0,0.625,1\n'
    """
    buffer = io.StringIO()
    writer = RecordWriter(buffer, channels)
    writer.write_header()
    for row in rows:
        writer.write_row(row)
        if writer.rows % 1000 == 0:
            yield buffer.getvalue()
            buffer.seek(0)
            buffer.truncate()
    yield buffer.getvalue()


class RunStore:
    """Reads and writes the runs of the lab's database."""

    def __init__(self, db: Database) -> None:
        self._db = db

    def owned_run(self, run_id: int, who: Principal) -> None:
        """Check that ``who`` may read run ``run_id``.

        Raises
        ------
        NotFoundError
            If there is no such run.
        AccessDeniedError
            If it belongs to another user, is over, and ``who`` is a student.
        """
        with self._db.read() as session:
            run = session.get(Run, run_id)
            if run is None:
                raise NotFoundError(f"no run {run_id}")
            _check_owner(run, who)

    def read(self, run_id: int) -> tuple[Run, dict[str, dict[str, Any]]]:
        """A run's row and each method's stored ``{"method", "params", "result"}`` by label.

        Raises
        ------
        NotFoundError
            If there is no such run.
        """
        with self._db.read() as session:
            run = session.get(Run, run_id)
            if run is None:
                raise NotFoundError(f"no run {run_id}")
            return run, _stored_results(session, run)

    def rows(self, who: Principal, rig_id: str | None, limit: int, user: str | None) -> list[Run]:
        """Run rows, newest first: a student's own, or everyone's for a teacher."""
        query = select(Run).order_by(Run.started_at.desc(), Run.id.desc()).limit(limit)
        if user is not None:
            name = normalize_username(user)
            if not who.is_teacher and name != who.username:
                raise AccessDeniedError(
                    f"students may list only their own runs; ask for user={who.username}"
                )
        if rig_id is not None:
            query = query.where(Run.rig_id == rig_id)
        with self._db.read() as session:
            if user is not None and who.is_teacher:
                owner = session.scalar(select(User.id).where(User.username == name))
                if owner is None:
                    raise NotFoundError(f"no user called {name!r}")
                query = query.where(Run.user_id == owner)
            elif not who.is_teacher:
                query = query.where(Run.user_id == who.user_id)
            return list(session.scalars(query))

    def samples(self, run_id: int) -> Iterator[StoredSample]:
        """Yield ``(k, t, u, y)`` of every stored sample of a run, in order."""
        with self._db.read() as session:
            rows = session.execute(
                select(Sample.k, Sample.t, Sample.u, Sample.y)
                .where(Sample.run_id == run_id)
                .order_by(Sample.k)
                .execution_options(yield_per=2000)
            )
            for row in rows:
                yield (row[0], row[1], row[2], row[3])

    def channels(self, run_id: int) -> tuple[ChannelSpec, ...]:
        """The channels of a run's stored samples, in record order.

        :data:`~thermolab.records.RUN_CHANNELS` and the extra channels of the
        first sample (by name; ``t,u,y,k`` for samples stored before revision
        0004, which have no timing).
        """
        with self._db.read() as session:
            first = session.execute(
                select(Sample.t_read, Sample.extra)
                .where(Sample.run_id == run_id)
                .order_by(Sample.k)
                .limit(1)
            ).first()
        if first is None or first[0] is None:
            return _EARLY_CHANNELS
        return (*RUN_CHANNELS, *(ChannelSpec(name) for name in first[1] or {}))

    def channel_rows(
        self, run_id: int, channels: Sequence[ChannelSpec]
    ) -> Iterator[tuple[float, ...]]:
        """Yield each stored sample's values of ``channels`` (from :meth:`channels`), in order.

        A value missing from a sample (an extra channel it lacks, a null) is NaN.
        """
        standard = [c.name for c in channels if c.name in _COLUMNS]
        extra = [c.name for c in channels if c.name not in _COLUMNS]
        order = [c.name for c in channels]
        with self._db.read() as session:
            rows = session.execute(
                select(*(_COLUMNS[name] for name in standard), Sample.extra)
                .where(Sample.run_id == run_id)
                .order_by(Sample.k)
                .execution_options(yield_per=2000)
            )
            for row in rows:
                values = dict(zip(standard, row, strict=False))
                stored = row[-1] or {}
                values.update({name: stored.get(name) for name in extra})
                yield tuple(math.nan if values[n] is None else values[n] for n in order)

    def record(self, run_id: int) -> dict[str, Any]:
        """A run's samples by channel, for ``export.json``.

        Returns
        -------
        dict
            ``{"channels": [ChannelSpec.to_dict(), ...], "samples": {name: [value, ...]}}``
            (non-finite values as ``None``), in record order.
        """
        channels = self.channels(run_id)
        columns: list[list[float]] = [[] for _ in channels]
        for row in self.channel_rows(run_id, channels):
            for column, value in zip(columns, row, strict=True):
                column.append(value)
        samples = {c.name: column for c, column in zip(channels, columns, strict=True)}
        for c in channels:
            if c.integer:
                samples[c.name] = [int(v) for v in samples[c.name]]
        return {"channels": [c.to_dict() for c in channels], "samples": json_safe(samples)}

    def save_end(
        self,
        run_id: int,
        status: RunStatus,
        reason: str,
        now: datetime,
        results: dict[str, tuple[dict[str, Any], dict[str, Any]]],
    ) -> None:
        """Store how a run ended and each method's ``(params, result)``."""
        with self._db.write() as session:
            for name, (params, data) in results.items():
                session.add(
                    MethodResultRow(
                        run_id=run_id,
                        label=name,
                        method=name,
                        params=json_safe(params),
                        result=json_safe(data),
                        created_at=now,
                    )
                )
            stored = session.scalar(
                select(func.count()).select_from(Sample).where(Sample.run_id == run_id)
            )
            session.execute(
                update(Run)
                .where(Run.id == run_id)
                .values(
                    status=status.value,
                    ended_at=now,
                    end_reason=reason,
                    samples_stored=stored or 0,
                )
            )


def _stored_results(session: Session, run: Run) -> dict[str, dict[str, Any]]:
    rows = session.scalars(select(MethodResultRow).where(MethodResultRow.run_id == run.id))
    return {
        row.label: {"method": row.method, "params": row.params, "result": row.result}
        for row in rows
    }


def status_of(reason: EndReason) -> RunStatus:
    """The stored status of a run that ended for ``reason``."""
    if reason is EndReason.COMPLETED:
        return RunStatus.FINISHED
    if reason in (EndReason.ENDED, EndReason.ABORTED):
        return RunStatus.STOPPED
    return RunStatus.FAILED


def _check_owner(run: Run, who: Principal) -> None:
    # A running run is on show to every watcher of its rig; once over it is its owner's.
    if run.status == RunStatus.RUNNING.value:
        return
    if not who.is_teacher and run.user_id != who.user_id:
        raise AccessDeniedError(f"run {run.id} belongs to another user")


def run_command(
    rig_id: str,
    control: ControlSession,
    who: Principal,
    now: datetime,
    kind: str,
    value: float | None,
    run_id: int | None,
    payload: dict[str, Any] | None,
) -> Command:
    """A command row of the rig's controller (``run_start``...)."""
    return Command(
        rig_id=rig_id,
        control_session_id=control.id,
        run_id=run_id,
        user_id=who.user_id,
        username=who.username,
        at=now,
        kind=kind,
        value=value,
        payload=None if payload is None else json_safe(payload),
        applied=True,
    )
