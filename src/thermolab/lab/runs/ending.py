"""The end of a run: how it ended, each method's result with its statistics, the timing.

When a run's :class:`~thermolab.runner.Experiment` returns its
:class:`~thermolab.runner.RunResult`, :func:`end_of_run` turns it into what
is stored with the run: the run's status and the reason in words, every
method's settings and result with the paper's figures (:mod:`.statistics`,
computed once, here), how well it kept its sampling times (:mod:`.timing`)
and, for a closed loop, the controller as it ended. :func:`save_end` writes
it, on the run's own thread (a run's row and samples are :mod:`.store`'s).

A rig host's run is sampled on the host and its end comes after its last
sample is stored (the host's outbox is sent in order): its timing is judged
on the stored samples by :func:`stored_timing`, which reads each sample's
``t_read`` and ``lateness`` (stored with it), so an end that comes late, after
a restart or a takeover, is judged the same way.
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import func, select, update

from thermolab.errors import ThermoLabError
from thermolab.ident.assess import judge_model
from thermolab.ident.online import OnlineIdentifier
from thermolab.ident.units import in_units_everywhere
from thermolab.ident.verdict import MIN_SAMPLES
from thermolab.jsonsafe import json_safe
from thermolab.lab.db import Database
from thermolab.lab.db.models import MethodResultRow, Run, RunStatus, Sample
from thermolab.lab.runs.active import ActiveRun
from thermolab.lab.runs.statistics import method_statistics
from thermolab.lab.runs.timing import timing_summary
from thermolab.runner import EndReason, RunResult
from thermolab.runner.results import MethodResult

__all__ = [
    "SERVER_STOPPED",
    "EndCause",
    "RunEnd",
    "end_of_run",
    "host_end_words",
    "method_results",
    "save_end",
    "status_of",
    "stored_timing",
]

log = logging.getLogger(__name__)

#: ``ActiveRun.stopped_by`` of the runs the server aborted as it stopped (stored interrupted).
SERVER_STOPPED = "the server stopped"


class EndCause(enum.StrEnum):
    """Why a rig host's run ended when nobody at the lab asked: its stored reason's code.

    Stored as ``"<code>: <the English detail>"``, as the runner's reasons
    (``"rig_fault: ..."``); the browser says each code in the reader's language
    (``runwords.js``, ``END_REASONS``).

    Attributes
    ----------
    LINK_LOST
        The host ENDed the run at its grace's end, no address of the lab
        answering (the network, or the lab's machine, away).
    HOST_AWAY
        The lab ENDed it: its host was away (not connected, or silent) past the
        grace, which took the rig out of service and ended the turn.
    OWNER_GONE
        The owner worker was gone (killed, stopped, hung) and no worker took
        the host's link in its grace: the host ENDed the run while the lab's
        machines answered, or the lab had stored the run interrupted by its
        server's stop.
    """

    LINK_LOST = "link_lost"
    HOST_AWAY = "host_away"
    OWNER_GONE = "owner_gone"


def host_end_words(
    reason: EndReason,
    message: str,
    *,
    cause: EndCause | None,
    away: str | None = None,
    asked_by: str | None = None,
    server_stopped: bool = False,
) -> str:
    """The stored end reason of a rig host's run: the real cause, whoever asked for the END.

    ``message`` is the host's (``RunEnded.message``); ``cause`` what it says
    of the host's own END at its grace's end (``None``: the host did not END
    it by itself). ``away``: the lab ENDed it because its host was away (the
    health fault's words). ``asked_by``: who asked for the END (a user, "end of
    the turn at the controls"). ``server_stopped``: the lab had stored the run
    interrupted as its server stopped (a restart): a host that lost its link
    then lost it because the owner went.
    """
    if cause is EndCause.LINK_LOST and server_stopped:
        cause = EndCause.OWNER_GONE
    if cause is not None:  # the host's own END: its cause, even if the lab also asked
        return f"{cause.value}: {message}"
    if reason is EndReason.ENDED and away is not None:
        return f"{EndCause.HOST_AWAY.value}: {away}"
    if reason is EndReason.ENDED and asked_by:
        return f"ended by {asked_by}"
    return reason.value + (f": {message}" if message else "")


@dataclass(frozen=True, slots=True)
class RunEnd:
    """What is stored when a run ends (what :func:`save_end` writes).

    Attributes
    ----------
    status : RunStatus
    reason : str
        How it ended, in words ("ended by ana", "rig_fault: ...").
    results : dict
        Each method's ``(settings, result)``, the result with its ``stats``.
    timing : dict
        :func:`~thermolab.lab.runs.timing.timing_summary` of the run (a rig
        host's: :func:`stored_timing`).
    control : dict or None
        The controller as it ended (a closed loop), else ``None``.
    """

    status: RunStatus
    reason: str
    results: dict[str, tuple[dict[str, Any], dict[str, Any]]]
    timing: dict[str, Any]
    control: dict[str, Any] | None


def end_of_run(active: ActiveRun, result: RunResult, *, simulated: bool) -> RunEnd:
    """Return what to store of the run ``active`` that ended with ``result``.

    ``simulated``: the rig is a twin (its timing is judged against its own clock).
    Each method's result: :func:`method_results`.
    """
    status = status_of(result.end_reason)
    if active.stopped_by == SERVER_STOPPED:
        status = RunStatus.INTERRUPTED
    reason = result.end_reason.value
    if result.message:
        reason = f"{reason}: {result.message}"
    if result.end_reason is EndReason.ENDED and active.stopped_by:
        reason = f"ended by {active.stopped_by}"
    pair = active.experiment.pair  # the identified pair, in its own units
    units = pair.units(result.rig)
    record = (result.t, *pair.columns(result.u, result.y, result.extra), result.dt)
    results = method_results(active.run_id, result.methods, active.identifiers, units, record)
    timing = timing_summary(result.t_read, result.lateness, result.dt, simulated=simulated)
    control = None if result.control is None else json_safe(result.control)
    return RunEnd(status, reason, results, timing, control)


Record = tuple[Any, Any, Any, float]
"""A run's record as the verdict reads it: times, inputs, outputs and the sample period."""


def method_results(
    run_id: int,
    methods: Mapping[str, MethodResult],
    identifiers: Mapping[str, OnlineIdentifier],
    units: tuple[str, str] | None = None,
    record: Record | None = None,
) -> dict[str, tuple[dict[str, Any], dict[str, Any]]]:
    """Each method's ``(settings, result)`` as a run stores them, the result with its figures.

    The one place a run's results are made, in-process (:func:`end_of_run`) or
    on a rig host's samples (:mod:`thermolab.lab.agents.estimates`). A method
    whose statistics fail keeps its result without them (logged): the figures
    are a summary and never cost the run. ``units``, the rig's input and output
    units: the methods' words (written in volts) then speak of them. With the
    run's ``record``, each final model is judged on it as ``thermolab identify``
    judges a file (:func:`thermolab.ident.assess.judge_model`): its ``trusted``
    is the verdict's, and a reason not to trust it is listed with its warnings.
    """
    results: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {}
    peers: dict[str, dict[str, Any]] = {}  # one output-error fit of the record for all
    for name, method in methods.items():
        identifier = identifiers.get(name)
        data = method.to_dict(trajectory=True)
        try:  # computed once, here, and stored with the result
            data["stats"] = method_statistics(name, identifier, data.get("latest"))
        except (ThermoLabError, ArithmeticError, ValueError) as exc:
            log.warning("run %s: statistics of %s failed: %s", run_id, name, exc)
        if record is not None and data.get("latest") is not None:
            try:
                _judge_latest(name, data, record, peers)
            except (ThermoLabError, ArithmeticError, ValueError) as exc:
                log.warning("run %s: the verdict on %s failed: %s", run_id, name, exc)
        if units is not None:
            data = in_units_everywhere(data, *units)
        results[name] = (dict(identifier.params) if identifier is not None else {}, data)
    return results


def _judge_latest(
    name: str, data: dict[str, Any], record: Record, peers: dict[str, dict[str, Any]]
) -> None:
    """The verdict on a method's last estimate, written into its stored result."""
    latest = data["latest"]
    extras = latest.setdefault("extras", {})
    if len(record[0]) < MIN_SAMPLES:
        return  # too short to judge: the warning-free rule stands
    valid = bool(latest.get("valid"))
    stats = data.get("stats") or {}
    t, u, y, dt = record
    verdict = judge_model(
        name,
        t,
        u,
        y,
        dt,
        K=latest.get("K") if valid else None,
        tau=latest.get("tau") if valid else None,
        theta=extras.get("theta"),
        warnings=list(extras.get("warnings") or []),
        converged=stats.get("converged"),
        reason=extras.get("reason"),
        peers=peers,
    )
    extras["trusted"] = verdict.trusted
    said = list(extras.get("warnings") or [])
    extras["warnings"] = [*(r for r in verdict.reasons if r not in said), *said]
    data["verdict"] = verdict.to_dict()


def stored_timing(db: Database, run_id: int, dt: float, *, simulated: bool) -> dict[str, Any]:
    """:func:`~thermolab.lab.runs.timing.timing_summary` of the run's stored samples.

    A rig host's run: each sample's ``t_read`` and ``lateness`` came with it
    and are stored with it, so the figures are the ones the host's runner would
    have given. Samples stored before revision 0004 (no timing) are left out.
    """
    with db.read() as session:
        rows = session.execute(
            select(Sample.t_read, Sample.lateness).where(Sample.run_id == run_id).order_by(Sample.k)
        ).all()
    timed = [(t, late) for t, late in rows if t is not None and late is not None]
    return timing_summary(
        [t_read for t_read, _ in timed], [late for _, late in timed], dt, simulated=simulated
    )


def status_of(reason: EndReason) -> RunStatus:
    """The stored status of a run that ended for ``reason``."""
    if reason is EndReason.COMPLETED:
        return RunStatus.FINISHED
    if reason in (EndReason.ENDED, EndReason.ABORTED):
        return RunStatus.STOPPED
    return RunStatus.FAILED


def save_end(db: Database, run_id: int, end: RunEnd, now: datetime) -> None:
    """Store how a run ended, each method's ``(params, result)``, the run's timing and,
    for a closed loop, its controller as it ended."""
    with db.write() as session:
        for name, (params, data) in end.results.items():
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
        meta = session.scalar(select(Run.meta).where(Run.id == run_id)) or {}
        session.execute(
            update(Run)
            .where(Run.id == run_id)
            .values(
                status=end.status.value,
                ended_at=now,
                end_reason=end.reason,
                samples_stored=stored or 0,
                # A new dict: the JSON column sees the change.
                meta={**meta, "timing": end.timing, "control_end": end.control},
            )
        )
