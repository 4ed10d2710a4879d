"""Per rig: use by a course's students, their queue waits, faults, hours powered.

Use, waits and failed runs count the course's students; rig faults and
hours powered are the rig's own, whoever was at the controls. Every figure is
one grouped query over all the course's rigs.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import Select, case, func, select
from sqlalchemy.orm import Session

from thermolab.lab.analytics.sql import at, clipped_seconds, percentile, seconds, seconds_between
from thermolab.lab.db.models import (
    ControlSession,
    LeaveReason,
    PowerState,
    QueueEntry,
    Run,
    RunStatus,
    TurnEndReason,
)
from thermolab.lab.db.power_models import PowerChange

__all__ = ["RigUse", "Waits", "faults", "powered", "queue_waits", "rig_use"]


@dataclass(frozen=True, slots=True)
class RigUse:
    """The course's students at one rig."""

    seconds: float = 0.0
    turns: int = 0
    students: int = 0
    runs: int = 0
    failed_runs: int = 0
    interlock_runs: int = 0


@dataclass(frozen=True, slots=True)
class Waits:
    """Waits from joining a rig's queue to getting control (seconds)."""

    count: int = 0
    median: float | None = None
    p90: float | None = None


def rig_use(
    session: Session, students: Select[int], start: datetime, end: datetime, now: datetime
) -> dict[str, RigUse]:
    """Hours at the controls, turns, distinct students and runs, per rig."""
    until = func.coalesce(ControlSession.ended_at, at("now", now))
    control = session.execute(
        select(
            ControlSession.rig_id,
            func.sum(clipped_seconds(ControlSession.started_at, until, start, end)),
            func.count(),
            func.count(func.distinct(ControlSession.user_id)),
        )
        .where(
            ControlSession.user_id.in_(students),
            ControlSession.started_at < at("to", end),
            until > at("from", start),
        )
        .group_by(ControlSession.rig_id)
    ).all()
    failed = Run.status == RunStatus.FAILED.value
    runs = session.execute(
        select(
            Run.rig_id,
            func.count(),
            func.sum(case((failed, 1), else_=0)),
            func.sum(case((failed & Run.end_reason.like("interlock%"), 1), else_=0)),
        )
        .where(
            Run.user_id.in_(students),
            Run.started_at >= at("from", start),
            Run.started_at < at("to", end),
        )
        .group_by(Run.rig_id)
    ).all()
    out: dict[str, RigUse] = {}
    for rig, total, turns, people in control:
        out[rig] = RigUse(seconds=seconds(total), turns=int(turns), students=int(people))
    for rig, count, failures, interlocks in runs:
        use = out.get(rig, RigUse())
        out[rig] = RigUse(
            use.seconds, use.turns, use.students, int(count), int(failures), int(interlocks)
        )
    return out


def queue_waits(
    session: Session, students: Select[int], start: datetime, end: datetime
) -> dict[str, Waits]:
    """Median and 90th percentile of the waits that ended in control inside the window."""
    waits = select(
        QueueEntry.rig_id.label("rig"),
        seconds_between(QueueEntry.joined_at, QueueEntry.left_at).label("wait"),
    ).where(
        QueueEntry.user_id.in_(students),
        QueueEntry.leave_reason == LeaveReason.PROMOTED.value,
        QueueEntry.left_at >= at("from", start),
        QueueEntry.left_at < at("to", end),
    )
    rows = session.execute(percentile(waits, "rig", "wait", {"median": (1, 2), "p90": (9, 10)}))
    return {
        rig: Waits(int(count), seconds(median), seconds(p90)) for rig, count, median, p90 in rows
    }


def faults(session: Session, start: datetime, end: datetime) -> dict[str, int]:
    """Turns a rig fault ended inside the window, per rig (anyone's turn)."""
    rows = session.execute(
        select(ControlSession.rig_id, func.count())
        .where(
            ControlSession.end_reason == TurnEndReason.RIG_FAULT.value,
            ControlSession.ended_at >= at("from", start),
            ControlSession.ended_at < at("to", end),
        )
        .group_by(ControlSession.rig_id)
    )
    return {rig: int(count) for rig, count in rows}


def powered(
    session: Session, start: datetime, end: datetime, now: datetime
) -> dict[str, tuple[float, datetime | None]]:
    """``{rig: (seconds powered inside the window, first recorded change)}``.

    Each recorded state lasts until the rig's next change (the current one
    until ``now``); every state but ``off`` counts as powered (a cool-down
    holds the rig at its cool-down input).
    """
    following = func.lead(PowerChange.at).over(
        partition_by=PowerChange.rig_id, order_by=(PowerChange.at, PowerChange.id)
    )
    spans = select(
        PowerChange.rig_id.label("rig"),
        PowerChange.state.label("state"),
        PowerChange.at.label("start"),
        func.coalesce(following, at("now", now)).label("stop"),
    ).subquery("spans")
    on = session.execute(
        select(spans.c.rig, func.sum(clipped_seconds(spans.c.start, spans.c.stop, start, end)))
        .where(
            spans.c.state != PowerState.OFF.value,
            spans.c.start < at("to", end),
            spans.c.stop > at("from", start),
        )
        .group_by(spans.c.rig)
    ).all()
    first = session.execute(
        select(PowerChange.rig_id, func.min(PowerChange.at)).group_by(PowerChange.rig_id)
    ).all()
    powered_for = {rig: seconds(total) for rig, total in on}
    out: dict[str, tuple[float, datetime | None]] = {}
    for rig, since in first:
        out[rig] = (powered_for.get(rig, 0.0), _instant(since))
    return out


def _instant(value: Any) -> datetime | None:
    # func.min over a UTCDateTime column keeps the column's type on both databases.
    return value if isinstance(value, datetime) or value is None else None
