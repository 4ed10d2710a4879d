"""The SQL of the access model: the statements of the hot path, built once.

Building a statement costs more than running it here, so the statements are
module constants with bound parameters.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import datetime

from sqlalchemy import bindparam, select
from sqlalchemy.orm import Session

from thermolab.errors import LabStartingError
from thermolab.lab.access.rules import Slot, Turn, TurnState, Waiting
from thermolab.lab.access.views import ControlRecord, QueueSlot, RigSnapshot
from thermolab.lab.config import LabConfig
from thermolab.lab.db.booking_models import Booking, BookingRig
from thermolab.lab.db.course_settings_models import CourseSettingsRow
from thermolab.lab.db.models import (
    Command,
    ControlSession,
    CourseMember,
    LeaveReason,
    PowerState,
    QueueEntry,
    RigRow,
    Run,
    RunStatus,
    TurnEndReason,
    User,
)
from thermolab.lab.db.power_models import PowerChange

__all__ = [
    "SERVER_STOPPED",
    "active",
    "head",
    "last_turn_end",
    "queue",
    "read_slots",
    "read_snapshot",
    "read_turn_state",
    "reset_for_startup",
    "run_active",
    "waiting",
    "write_transition",
]

SERVER_STOPPED = "the server stopped during the run"
"""The end reason of a run whose server stopped (start-up recovery, a takeover)."""


class _Q:
    """The statements of the hot path, with bound parameters."""

    _waiting = (QueueEntry.rig_id == bindparam("rig"), QueueEntry.left_at.is_(None))
    active = select(ControlSession).where(
        ControlSession.rig_id == bindparam("rig"), ControlSession.ended_at.is_(None)
    )
    queue = select(QueueEntry).where(*_waiting).order_by(QueueEntry.ticket)
    head = queue.limit(1)
    waiting = select(QueueEntry).where(*_waiting, QueueEntry.user_id == bindparam("user"))
    run_active = (
        select(Run.id)
        .where(Run.rig_id == bindparam("rig"), Run.status == RunStatus.RUNNING.value)
        .limit(1)
    )
    queue_rows = (
        select(
            QueueEntry.user_id,
            User.username,
            QueueEntry.ticket,
            QueueEntry.joined_at,
            QueueEntry.last_heartbeat_at,
        )
        .join(User, User.id == QueueEntry.user_id)
        .where(*_waiting)
        .order_by(QueueEntry.ticket)
    )
    slots = (
        select(Booking.id, Booking.course_id, Booking.starts_at, Booking.ends_at)
        .join(BookingRig, BookingRig.booking_id == Booking.id)
        .where(BookingRig.rig_id == bindparam("rig"), Booking.ends_at > bindparam("now"))
        .order_by(Booking.starts_at)
        .limit(2)
    )
    last_input = (
        select(Command.value)
        .where(Command.control_session_id == bindparam("control"), Command.kind == "input")
        .order_by(Command.at.desc(), Command.id.desc())
        .limit(1)
    )


def active(session: Session, rig_id: str) -> ControlSession | None:
    """The rig's active control session."""
    return session.scalars(_Q.active, {"rig": rig_id}).one_or_none()


def last_turn_end(session: Session, rig_id: str, user_id: int) -> tuple[str, str | None] | None:
    """How ``user_id``'s latest ended turn at the rig ended: ``(end_reason, ended_by)``."""
    row = session.execute(
        select(ControlSession.end_reason, ControlSession.ended_by)
        .where(
            ControlSession.rig_id == rig_id,
            ControlSession.user_id == user_id,
            ControlSession.ended_at.is_not(None),
        )
        .order_by(ControlSession.ended_at.desc(), ControlSession.id.desc())
        .limit(1)
    ).first()
    return None if row is None or row[0] is None else (row[0], row[1])


def queue(session: Session, rig_id: str) -> list[QueueEntry]:
    """The rig's queue, in ticket order."""
    return list(session.scalars(_Q.queue, {"rig": rig_id}))


def head(session: Session, rig_id: str) -> QueueEntry | None:
    """The first in the rig's queue."""
    return session.scalars(_Q.head, {"rig": rig_id}).first()


def waiting(session: Session, rig_id: str, user_id: int) -> QueueEntry | None:
    """``user_id``'s place in the rig's queue."""
    return session.scalars(_Q.waiting, {"rig": rig_id, "user": user_id}).one_or_none()


def run_active(session: Session, rig_id: str) -> bool:
    """Whether a run samples the rig."""
    return session.scalar(_Q.run_active, {"rig": rig_id}) is not None


def run_ends_at(session: Session, rig_id: str) -> datetime | None:
    """The planned end of the run sampling the rig (``None``: no run, or none planned)."""
    meta = session.scalar(
        select(Run.meta).where(Run.rig_id == rig_id, Run.status == RunStatus.RUNNING.value)
    )
    ends_at = None if meta is None else meta.get("ends_at")
    return None if ends_at is None else datetime.fromisoformat(ends_at)


def read_slots(session: Session, rig_id: str, now: datetime, users: set[int]) -> tuple[Slot, ...]:
    """The rig's slot going on at ``now`` and the next one, with which of ``users`` each admits
    and the course's limits.

    Slots of a rig never overlap, so the first two not yet ended hold the
    current one (if any) and the one the rules meet next.
    """
    rows = session.execute(_Q.slots, {"rig": rig_id, "now": now}).all()
    if not rows:
        return ()
    courses = {course for _, course, _, _ in rows}
    members: dict[int, set[int]] = {course: set() for course in courses}
    if users:
        for course, user in session.execute(
            select(CourseMember.course_id, CourseMember.user_id).where(
                CourseMember.course_id.in_(courses), CourseMember.user_id.in_(users)
            )
        ):
            members[course].add(user)
    limits = {
        course: tuple(sorted(values.items()))
        for course, values in session.execute(
            select(CourseSettingsRow.course_id, CourseSettingsRow.values).where(
                CourseSettingsRow.course_id.in_(courses)
            )
        )
    }
    return tuple(
        Slot(booking, course, start, end, frozenset(members[course]), limits.get(course, ()))
        for booking, course, start, end in rows
    )


def read_snapshot(session: Session, rig_id: str, now: datetime) -> RigSnapshot:
    """Read a rig's access state.

    Raises
    ------
    ConflictError
        If the rig is configured but not yet in the table (start-up has not run).
    """
    rig = session.get(RigRow, rig_id, populate_existing=True)
    if rig is None:
        # Configured but not yet in the table: start-up has not run.
        raise LabStartingError(f"rig {rig_id!r} is not ready yet; the lab is starting")
    control = active(session, rig_id)
    # Plain rows, not ORM objects: a class-sized queue is read on every look at the rig.
    rows = session.execute(_Q.queue_rows, {"rig": rig_id}).all()
    slots = tuple(
        QueueSlot(user_id, name, ticket, i + 1, joined, seen)
        for i, (user_id, name, ticket, joined, seen) in enumerate(rows)
    )
    last_input = None
    if control is not None:
        last_input = session.scalar(_Q.last_input, {"control": control.id})
    users = {place.user_id for place in slots}
    if control is not None and control.user_id is not None:
        users.add(control.user_id)
    return RigSnapshot(
        id=rig.id,
        title=rig.title,
        in_service=rig.in_service,
        power=PowerState(rig.power_state),
        fault=rig.fault,
        needs_cooldown=rig.needs_cooldown,
        cooling_since=rig.cooling_since,
        vacant_since=rig.vacant_since,
        ambient_output=rig.ambient_output,
        controller=None
        if control is None
        else ControlRecord(
            control.id,
            control.user_id,
            control.username,
            control.started_at,
            control.deadline,
            control.last_heartbeat_at,
            control.last_activity_at,
            script=control.token_id is not None,
        ),
        queue=slots,
        run_active=run_active(session, rig_id),
        last_input=last_input,
        run_ends_at=run_ends_at(session, rig_id),
        slots=read_slots(session, rig_id, now, users),
    )


def read_turn_state(
    session: Session, rig: RigRow, now: datetime
) -> tuple[TurnState, ControlSession | None, list[QueueEntry]]:
    """The rig's turn state, with the rows it was read from (control, queue)."""
    session.flush()
    control = active(session, rig.id)
    entries = queue(session, rig.id)
    turn = None
    if control is not None:
        turn = Turn(
            control.user_id,
            control.started_at,
            control.deadline,
            control.last_heartbeat_at,
            control.last_activity_at,
        )
    state = TurnState(
        in_service=rig.in_service,
        faulted=rig.fault is not None,
        power=PowerState(rig.power_state),
        needs_cooldown=rig.needs_cooldown,
        cooling_since=rig.cooling_since,
        vacant_since=rig.vacant_since,
        ambient_output=rig.ambient_output,
        turn=turn,
        queue=tuple(Waiting(e.user_id, e.last_heartbeat_at) for e in entries),
        run_active=run_active(session, rig.id),
    )
    users = {e.user_id for e in entries}
    if control is not None and control.user_id is not None:
        users.add(control.user_id)
    state = replace(state, slots=read_slots(session, rig.id, now, users))
    return state, control, entries


def write_transition(
    session: Session,
    rig: RigRow,
    control: ControlSession | None,
    entries: list[QueueEntry],
    after: TurnState,
    now: datetime,
    *,
    by: str | None = None,
) -> None:
    """Write a transition of the turn rules to the rig's rows."""
    if after.ended is not None and control is not None:
        control.ended_at = after.ended.at
        control.end_reason = after.ended.reason.value
        control.ended_by = by
    place = {entry.user_id: entry for entry in entries}
    for waiting, at in after.left:
        place[waiting.user_id].left_at = at
        place[waiting.user_id].leave_reason = LeaveReason.CLIENT_GONE.value
    for waiting, at in after.booked_out:
        place[waiting.user_id].left_at = at
        place[waiting.user_id].leave_reason = LeaveReason.BOOKED.value
    new_turn = after.turn is not None and (control is None or after.ended is not None)
    if after.turn is not None and new_turn and after.turn.user_id is not None:
        head = place[after.turn.user_id]
        head.left_at = now
        head.leave_reason = LeaveReason.PROMOTED.value
        session.flush()
        user = session.get(User, head.user_id)
        session.add(
            ControlSession(
                rig_id=rig.id,
                user_id=head.user_id,
                username=user.username if user is not None else "?",
                started_at=after.turn.started_at,
                deadline=after.turn.deadline,
                last_heartbeat_at=after.turn.last_heartbeat_at,
                last_activity_at=after.turn.last_activity_at,
                token_id=head.token_id,
            )
        )
    if rig.power_state != after.power.value:
        rig.power_state = after.power.value
        rig.power_changed_at = now
        session.add(PowerChange(rig_id=rig.id, at=now, state=after.power.value))
    rig.needs_cooldown = after.needs_cooldown
    rig.cooling_since = after.cooling_since
    rig.vacant_since = after.vacant_since
    rig.ambient_output = after.ambient_output
    session.flush()


def reset_for_startup(session: Session, config: LabConfig, now: datetime) -> None:
    """Bring the rigs table in line with ``config`` after a (re)start (see the service)."""
    cooling = {rig.id: config.rig(rig.id).cooldown.enabled for rig in config.rigs}
    existing = {rig.id: rig for rig in session.scalars(select(RigRow))}
    was = {rig.id: rig.power_state for rig in existing.values()}
    for rig in existing.values():
        rig.configured = False
    for cfg in config.rigs:
        row = existing.get(cfg.id)
        if row is None:
            row = RigRow(
                id=cfg.id,
                in_service=True,
                next_ticket=1,
                created_at=now,
                needs_cooldown=False,
                ambient_output=None,
            )
            session.add(row)
        row.title = cfg.title
        row.spec = cfg.spec
        row.configured = True
        row.power_state = PowerState.OFF.value
        row.power_changed_at = now
        row.vacant_since = now
        row.cooling_since = None
        row.fault = None
        row.fault_at = None
        row.updated_at = now
        if cfg.cooldown.ambient is not None:
            row.ambient_output = cfg.cooldown.ambient
    session.flush()
    for cfg in config.rigs:
        # A new rig, or one the previous server left powered: its history says off from now.
        if was.get(cfg.id) != PowerState.OFF.value:
            session.add(PowerChange(rig_id=cfg.id, at=now, state=PowerState.OFF.value))
    for control in session.scalars(select(ControlSession).where(ControlSession.ended_at.is_(None))):
        control.ended_at = now
        control.end_reason = TurnEndReason.SERVER_RESTART.value
        if control.rig_id in existing and cooling.get(control.rig_id, False):
            existing[control.rig_id].needs_cooldown = True
    for entry in session.scalars(select(QueueEntry).where(QueueEntry.left_at.is_(None))):
        entry.left_at = now
        entry.leave_reason = LeaveReason.SERVER_RESTART.value
    for run in session.scalars(select(Run).where(Run.status == RunStatus.RUNNING.value)):
        run.status = RunStatus.INTERRUPTED.value
        run.ended_at = now
        run.end_reason = SERVER_STOPPED
