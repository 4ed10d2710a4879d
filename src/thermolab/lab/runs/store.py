"""Where runs are kept: samples as they come, results at the end, and reading them back.

Every sample goes to the ``samples`` table through :class:`DatabaseRecorder`,
which the runner calls once per sample; it only appends to a buffer, and a
writer thread inserts the buffer every half second, so a crash of the server
loses at most about half a second of samples. At the end the methods'
results (final estimate, trajectories and statistics) go to
``method_results`` and the run row records how it ended
(:func:`thermolab.lab.runs.ending.save_end`). A run's row is made in the controller's locked
transaction (:func:`add_run`) and keeps the run's channels as specs (name,
unit, role, description: :func:`run_channels`, ``meta["channels"]``).

A sample keeps every channel of the run (:data:`thermolab.records.RUN_CHANNELS`
and the extra channels a rig or controller publishes, see
:class:`~thermolab.lab.db.models.Sample`); reading them back by channel and
the exports are :mod:`thermolab.lab.runs.export`.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    NotFoundError,
    PreviousRunEndingError,
    RunInProgressError,
)
from thermolab.jsonsafe import json_safe
from thermolab.lab.accounts.security import normalize_username
from thermolab.lab.accounts.users import Principal
from thermolab.lab.classes.authorize import reads_as_group_mate
from thermolab.lab.db import Database
from thermolab.lab.db.models import (
    Command,
    ControlSession,
    MethodResultRow,
    Run,
    RunStatus,
    User,
)
from thermolab.records import INPUT, OUTPUT, RUN_CHANNELS, ChannelSpec

__all__ = [
    "RunRecord",
    "RunStore",
    "add_run",
    "channel_specs",
    "record_of",
    "run_channels",
    "run_command",
]

log = logging.getLogger(__name__)


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
    ``channels`` describes every channel of its samples
    (:meth:`~thermolab.records.ChannelSpec.to_dict`, record order).
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
    channels: list[dict[str, str]] = field(default_factory=list)

    # A closed-loop run's controller: the loop's state (mode, set point, gains,
    # adaptive), live while it runs, as it ended afterwards; None for an open loop.
    control: dict[str, Any] | None = None


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
            If it belongs to another user, is over, and ``who`` is a student
            who is not the owner's lab group mate
            (:func:`~thermolab.lab.classes.authorize.reads_as_group_mate`).
        """
        with self._db.read() as session:
            run = session.get(Run, run_id)
            if run is None:
                raise NotFoundError(f"no run {run_id}")
            _check_owner(session, run, who)

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


def _stored_results(session: Session, run: Run) -> dict[str, dict[str, Any]]:
    rows = session.scalars(select(MethodResultRow).where(MethodResultRow.run_id == run.id))
    return {
        row.label: {"method": row.method, "params": row.params, "result": row.result}
        for row in rows
    }


def _check_owner(session: Session, run: Run, who: Principal) -> None:
    # A running run is on show to every watcher of its rig; once over it is its
    # owner's, every teacher's and (read only) the owner's lab group mates'.
    if run.status == RunStatus.RUNNING.value:
        return
    if who.is_teacher or run.user_id == who.user_id:
        return
    if not reads_as_group_mate(session, run, who):
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


def run_channels(
    input_unit: str, output_unit: str, extra: Sequence[ChannelSpec] = ()
) -> tuple[ChannelSpec, ...]:
    """A run's channels: :data:`~thermolab.records.RUN_CHANNELS` in the rig's units, then ``extra``.

    ``extra`` are what a rig or controller publishes (``Experiment.channels``
    after the standard ones: a PID's ``r, u_pid, e, auto``...).

    Examples
    --------
    >>> [(c.name, c.unit) for c in run_channels("%", "degC")[1:3]]
    [('u', '%'), ('y', 'degC')]
    """
    units = {INPUT.name: input_unit, OUTPUT.name: output_unit}
    standard = tuple(replace(c, unit=units.get(c.name, c.unit)) for c in RUN_CHANNELS)
    return (*standard, *extra)


def add_run(
    session: Session,
    control: ControlSession,
    who: Principal,
    now: datetime,
    *,
    settings: dict[str, Any],
    meta: dict[str, Any],
    channels: Sequence[ChannelSpec],
) -> int:
    """Make a run's row and its ``run_start`` command in the controller's transaction.

    ``settings`` is what was asked (``dt``, ``samples``, ``signal``,
    ``setpoint``, ``methods``...), as stored; ``meta`` what the run keeps
    besides (operating point, planned end); the channels are kept as specs.

    Raises
    ------
    RunInProgressError
        If a run of this turn is already going on the rig.
    PreviousRunEndingError
        If the previous turn's run is still going (storing its end).
    """
    rig_id = control.rig_id
    running = session.execute(
        select(Run.id, Run.control_session_id).where(
            Run.rig_id == rig_id, Run.status == RunStatus.RUNNING.value
        )
    ).first()
    if running is not None and running.control_session_id == control.id:
        raise RunInProgressError(f"run {running.id} is already going on rig {rig_id!r}")
    if running is not None:
        raise PreviousRunEndingError(
            f"run {running.id} of the previous turn at rig {rig_id!r} is still ending; "
            "START again in a few seconds"
        )
    run = Run(
        rig_id=rig_id,
        user_id=who.user_id,
        control_session_id=control.id,
        status=RunStatus.RUNNING.value,
        dt=settings["dt"],
        n_samples=settings["samples"],
        signal=settings["signal"],
        setpoint=settings["setpoint"],
        methods=list(settings["methods"]),
        meta={
            "settings": settings,
            "username": who.username,
            **meta,
            "channels": [_spec_json(c) for c in channels],
        },
        started_at=now,
        samples_stored=0,
    )
    session.add(run)
    session.flush()
    session.add(run_command(rig_id, control, who, now, "run_start", None, run.id, settings))
    return run.id


def record_of(
    run: Run, results: dict[str, Any], samples_taken: int, control: dict[str, Any] | None = None
) -> RunRecord:
    """A run's row as a :class:`RunRecord` (``results``, progress and the live controller
    given by the caller; an ended run's controller is the one stored at its end)."""
    meta = run.meta
    ends_at = meta.get("ends_at")  # None for runs stored before it was kept
    stored = meta.get("channels")
    return RunRecord(
        id=run.id,
        rig_id=run.rig_id,
        username=str(meta.get("username", "")),
        user_id=run.user_id,
        status=run.status,
        dt=run.dt,
        samples=run.n_samples,
        samples_stored=run.samples_stored,
        samples_taken=samples_taken,
        signal=run.signal,
        setpoint=run.setpoint,
        methods=list(run.methods),
        settings=dict(meta.get("settings", {})),
        started_at=run.started_at,
        ended_at=run.ended_at,
        end_reason=run.end_reason,
        results=results,
        operating_point=meta.get("operating_point"),
        ends_at=None if ends_at is None else datetime.fromisoformat(ends_at),
        timing=meta.get("timing"),
        channels=[] if stored is None else [c.to_dict() for c in channel_specs(stored)],
        control=control if control is not None else meta.get("control_end"),
    )


def _spec_json(spec: ChannelSpec) -> dict[str, Any]:
    # to_dict() is what clients see; the store keeps how the CSV writes it too.
    return {**spec.to_dict(), "integer": spec.integer, "digits": spec.digits}


def channel_specs(stored: Sequence[dict[str, Any]]) -> tuple[ChannelSpec, ...]:
    """The channel specs stored with a run (``meta["channels"]``, see :func:`add_run`)."""
    return tuple(ChannelSpec(**item) for item in stored)
