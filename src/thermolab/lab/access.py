"""Who may do what with a rig: the paper's access model, made exact.

Any logged-in user may watch any rig. One user at a time controls a rig;
asking for control takes it if the rig is free, or joins a FIFO queue. A turn
ends when the controller releases it, when the rig's time limit runs out (a
teacher may extend or cut it), when the controller has given no command for
the idle limit, when their client has been silent for the client timeout, when
a teacher kicks them, or when the rig faults; the head of the queue then gets
control at once (after a cool-down if the rig is configured for one). Every
end is recorded with its reason.

How "exactly one controller" is guaranteed, under any interleaving:

1. Every decision about a rig's controller or queue runs in one database
   transaction that first takes the rig's lock (:meth:`Database.lock_rig`:
   ``SELECT ... FOR UPDATE`` on PostgreSQL, ``BEGIN IMMEDIATE`` on SQLite),
   so such transactions on one rig happen one after the other.
2. A request for control always takes a ticket from the rig's counter and
   joins the queue; control is then given to the head of the queue, by
   ticket. A hundred simultaneous requests get tickets 1..100, one of them
   controls and the others have distinct queue positions.
3. The database refuses a second active control session on a rig (a partial
   unique index), whatever the code above does.

Time comes from an injected :class:`~thermolab.lab.clock.LabClock`. Limits
are checked whenever the rig is looked at (any request) and by the lab's
periodic sweep, and an end is dated at the instant the limit was reached, so
the record does not depend on when the check ran.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Literal, Protocol, TypeVar

from sqlalchemy import bindparam, select
from sqlalchemy.orm import Session

from thermolab.errors import AccessDeniedError, ConflictError, InvalidParameterError
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig, RigConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import (
    Command,
    ControlSession,
    LeaveReason,
    PowerState,
    QueueEntry,
    RigRow,
    Role,
    Run,
    RunStatus,
    TurnEndReason,
    User,
    UTCDateTime,
)
from thermolab.lab.devices import PublishedRig
from thermolab.lab.presence import Presence, Watcher
from thermolab.lab.users import Principal

__all__ = [
    "AccessService",
    "AccessView",
    "CommandRecord",
    "ControlRecord",
    "QueueSlot",
    "RigMonitor",
    "RigSnapshot",
    "RigView",
]

T = TypeVar("T")
AccessRole = Literal["controller", "queued", "watcher"]
RigStateName = Literal["off", "starting", "free", "in_use", "cooldown", "fault", "out_of_service"]

# A heartbeat is written at most this often per client, so that polling stays cheap.
_HEARTBEAT_WRITE_INTERVAL = timedelta(seconds=1)
_MAX_EXTENSION = 24 * 3600.0


class RigMonitor(Protocol):
    """What the access model needs to know of a live rig (the hub provides it)."""

    def published(self, rig_id: str) -> PublishedRig:
        """The rig's input range, units and safe input."""
        ...

    def reading(self, rig_id: str) -> tuple[float, datetime] | None:
        """The latest reading of the rig's output and when it was taken, if any."""
        ...


@dataclass(frozen=True, slots=True)
class ControlRecord:
    """The active control session of a rig."""

    id: int
    user_id: int | None
    username: str
    started_at: datetime
    deadline: datetime
    last_heartbeat_at: datetime
    last_activity_at: datetime


@dataclass(frozen=True, slots=True)
class QueueSlot:
    """A user waiting for a rig (``position`` counts from 1)."""

    user_id: int
    username: str
    ticket: int
    position: int
    joined_at: datetime
    last_heartbeat_at: datetime


@dataclass(frozen=True, slots=True)
class RigSnapshot:
    """A rig's access state, read in one transaction."""

    id: str
    title: str
    in_service: bool
    power: PowerState
    fault: str | None
    needs_cooldown: bool
    cooling_since: datetime | None
    vacant_since: datetime | None
    ambient_output: float | None
    controller: ControlRecord | None
    queue: tuple[QueueSlot, ...]
    run_active: bool
    last_input: float | None

    def slot_of(self, user_id: int) -> QueueSlot | None:
        """Return the queue slot of ``user_id``, if queued."""
        for slot in self.queue:
            if slot.user_id == user_id:
                return slot
        return None


@dataclass(frozen=True, slots=True)
class AccessView:
    """A rig's access state as one user sees it (the Go-Lab Smart Device names).

    Attributes
    ----------
    role : {"controller", "queued", "watcher"}
    queue_size : int
        Users waiting.
    queue_position : int or None
        The caller's place in the queue (1 = next), if queued.
    estimated_time_until_control : float or None
        Seconds until the caller would control the rig: 0 for the controller;
        for a queued user, an upper bound assuming everyone ahead uses their
        full time (and cool-down); for a watcher, the same bound if they asked
        now. ``None`` when the rig cannot be controlled (fault, out of service).
    time_left : float or None
        The controller's seconds until the time limit, shown to everyone (it
        tells watchers and the queue when the rig changes hands); ``None``
        when nobody controls the rig.
    idle_time_left : float or None
        The controller's seconds until the idle limit, for the controller only
        (``None`` otherwise, or if no idle limit applies).
    controller : str or None
        Who controls the rig.
    watchers : int
        How many users watch the rig.
    """

    role: AccessRole
    queue_size: int
    queue_position: int | None
    estimated_time_until_control: float | None
    time_left: float | None
    idle_time_left: float | None
    controller: str | None
    watchers: int


@dataclass(frozen=True, slots=True)
class RigView:
    """A rig as one user sees it: state, limits and access.

    ``queue`` and ``watcher_list`` are filled for teachers only.
    """

    id: str
    title: str
    kind: str
    state: RigStateName
    in_service: bool
    fault: str | None
    published: PublishedRig
    last_input: float | None
    config: RigConfig
    client_timeout: float
    access: AccessView
    queue: tuple[QueueSlot, ...] | None = None
    watcher_list: tuple[Watcher, ...] | None = None
    snapshot: RigSnapshot | None = field(default=None, repr=False)


@dataclass(frozen=True, slots=True)
class CommandRecord:
    """An input command accepted from a controller."""

    id: int
    rig_id: str
    control_session: int
    u: float
    at: datetime


class AccessService:
    """The access model over the lab's database.

    Parameters
    ----------
    db : Database
    config : LabConfig
    clock : LabClock
    monitor : RigMonitor
        Published ranges and readings of the rigs.
    presence : Presence
        Watchers per rig.
    on_change : callable, optional
        Called with a rig id after every committed change of its access state
        (the lab reconciles the live rig and notifies watchers).
    """

    def __init__(
        self,
        db: Database,
        config: LabConfig,
        clock: LabClock,
        monitor: RigMonitor,
        presence: Presence,
        on_change: Callable[[str], None] | None = None,
    ) -> None:
        self._db = db
        self._config = config
        self._clock = clock
        self._monitor = monitor
        self._presence = presence
        self._timeout = timedelta(seconds=config.access.client_timeout)
        self._on_change = on_change

    # -- start-up --------------------------------------------------------------------

    def startup(self) -> None:
        """Bring the rigs table in line with the configuration after a (re)start.

        New rigs are added; rigs no longer configured are kept for history but
        hidden; every control session and queue place left from before ends
        with reason ``server_restart``; every rig is powered off (its safe state).
        """
        now = self._clock.now()
        with self._db.write() as session:
            existing = {rig.id: rig for rig in session.scalars(select(RigRow))}
            for rig in existing.values():
                rig.configured = False
            for cfg in self._config.rigs:
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
            for control in session.scalars(
                select(ControlSession).where(ControlSession.ended_at.is_(None))
            ):
                control.ended_at = now
                control.end_reason = TurnEndReason.SERVER_RESTART.value
                if control.rig_id in existing and self._cooldown(control.rig_id):
                    existing[control.rig_id].needs_cooldown = True
            for entry in session.scalars(select(QueueEntry).where(QueueEntry.left_at.is_(None))):
                entry.left_at = now
                entry.leave_reason = LeaveReason.SERVER_RESTART.value
            for run in session.scalars(select(Run).where(Run.status == RunStatus.RUNNING.value)):
                run.status = RunStatus.INTERRUPTED.value
                run.ended_at = now
                run.end_reason = "the server stopped during the run"

    # -- reading ---------------------------------------------------------------------

    def snapshot(self, rig_id: str) -> RigSnapshot:
        """Read a rig's access state (no side effect).

        Raises
        ------
        NotFoundError
            If the lab has no such rig.
        """
        self._config.rig(rig_id)
        with self._db.read() as session:
            return self._snapshot(session, rig_id)

    def desired(self, rig_id: str) -> tuple[PowerState, int | None]:
        """Return the rig's power state and active control session id (for the hub)."""
        with self._db.read() as session:
            power = session.scalar(select(RigRow.power_state).where(RigRow.id == rig_id))
            control = session.scalar(
                select(ControlSession.id).where(
                    ControlSession.rig_id == rig_id, ControlSession.ended_at.is_(None)
                )
            )
        return PowerState(power or PowerState.OFF.value), control

    def view(self, rig_id: str, who: Principal, *, heartbeat: bool = True) -> RigView:
        """Return a rig as ``who`` sees it.

        Looking at a rig counts as a heartbeat of the caller's control or queue
        place, and as watching it, unless ``heartbeat`` is false (a list of every
        rig is not watching them all); either way any limit that has run out is
        applied.

        Raises
        ------
        NotFoundError
            If the lab has no such rig.
        """
        cfg = self._config.rig(rig_id)
        now = self._clock.now()
        if heartbeat:
            self._presence.touch(rig_id, who.username)
        with self._db.read() as session:
            snap = self._snapshot(session, rig_id)
        if self._due(snap, cfg, now) or (heartbeat and self._heartbeat_stale(snap, who, now)):
            return self._write(rig_id, who, lambda s, rig, t: None, heartbeat=heartbeat)[0]
        return self._render(snap, cfg, who, now)

    def views(self, who: Principal) -> list[RigView]:
        """Return every configured rig as ``who`` sees it (no heartbeat, and not watching)."""
        return [self.view(rig.id, who, heartbeat=False) for rig in self._config.rigs]

    # -- the caller's own control ------------------------------------------------------

    def request_control(self, rig_id: str, who: Principal) -> RigView:
        """Take control of a free rig, or join its queue (idempotent).

        Raises
        ------
        NotFoundError
            If the lab has no such rig.
        ConflictError
            If the rig is out of service or faulted.
        """

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            if not rig.in_service:
                raise ConflictError(f"rig {rig.id!r} is out of service; ask a teacher")
            if rig.fault is not None:
                raise ConflictError(
                    f"rig {rig.id!r} has a fault ({rig.fault}); a teacher must clear it first"
                )
            control = self._active(session, rig.id)
            if control is not None and control.user_id == who.user_id:
                return
            if self._waiting(session, rig.id, who.user_id) is not None:
                return
            ticket = rig.next_ticket
            rig.next_ticket = ticket + 1
            session.add(
                QueueEntry(
                    rig_id=rig.id,
                    user_id=who.user_id,
                    ticket=ticket,
                    joined_at=now,
                    last_heartbeat_at=now,
                )
            )
            session.flush()

        return self._write(rig_id, who, act)[0]

    def release(self, rig_id: str, who: Principal) -> RigView:
        """Give up control, or leave the queue (no effect for a mere watcher).

        Raises
        ------
        NotFoundError
            If the lab has no such rig.
        """

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            control = self._active(session, rig.id)
            if control is not None and control.user_id == who.user_id:
                self._end(session, rig, control, TurnEndReason.RELEASED, now, now)
                return
            entry = self._waiting(session, rig.id, who.user_id)
            if entry is not None:
                entry.left_at = now
                entry.leave_reason = LeaveReason.LEFT.value

        return self._write(rig_id, who, act)[0]

    def heartbeat(self, rig_id: str, who: Principal) -> RigView:
        """Say the caller's client is still there; return the rig as they see it."""
        return self._write(rig_id, who, lambda s, rig, now: None)[0]

    def within_control(
        self,
        rig_id: str,
        who: Principal,
        action: str,
        act: Callable[[Session, RigRow, ControlSession, datetime], T],
    ) -> tuple[T, int]:
        """Run ``act`` in the rig's locked transaction if ``who`` controls the rig.

        The turn counts as active (the idle limit restarts). ``act`` must check
        before it changes anything (a refusal it raises is raised after the
        commit of the limits applied meanwhile).

        Returns
        -------
        tuple
            What ``act`` returned, and the id of the control session.

        Raises
        ------
        AccessDeniedError
            If ``who`` does not control the rig (the message says ``action``).
        """
        out: list[tuple[T, int]] = []

        def guarded(session: Session, rig: RigRow, now: datetime) -> None:
            control = self._active(session, rig.id)
            if control is None or control.user_id != who.user_id:
                holder = "nobody" if control is None else "another user"
                raise AccessDeniedError(
                    f"only the controller of rig {rig.id!r} may {action}, and "
                    f"{holder} controls it now; ask for control first"
                )
            control.last_activity_at = now
            out.append((act(session, rig, control, now), control.id))

        self._write(rig_id, who, guarded)
        return out[0]

    def record_input(
        self, rig_id: str, who: Principal, u: float, *, run_id: int | None = None
    ) -> CommandRecord:
        """Accept an input command from the rig's controller and record it.

        Raises
        ------
        NotFoundError
            If the lab has no such rig.
        AccessDeniedError
            If ``who`` does not control the rig.
        InvalidParameterError
            If ``u`` is not a finite number inside the rig's published range.
        """
        published = self._monitor.published(rig_id)
        value = _check_input(u, published, rig_id)

        def act(
            session: Session, rig: RigRow, control: ControlSession, now: datetime
        ) -> CommandRecord:
            command = Command(
                rig_id=rig.id,
                control_session_id=control.id,
                run_id=run_id,
                user_id=who.user_id,
                username=who.username,
                at=now,
                kind="input",
                value=value,
                payload=None,
                applied=False,
            )
            session.add(command)
            session.flush()
            return CommandRecord(command.id, rig.id, control.id, value, now)

        return self.within_control(rig_id, who, "change its input", act)[0]

    def mark_applied(self, command_id: int) -> None:
        """Record that a command reached the device."""
        with self._db.write() as session:
            command = session.get(Command, command_id)
            if command is not None:
                command.applied = True

    # -- teachers ------------------------------------------------------------------------

    def extend(self, rig_id: str, who: Principal, seconds: float) -> RigView:
        """Move the controller's time limit by ``seconds`` (negative cuts it).

        A cut to now or earlier ends the turn (reason ``time_limit``).

        Raises
        ------
        AccessDeniedError
            If ``who`` is not a teacher.
        InvalidParameterError
            If ``seconds`` is not finite or larger than a day either way.
        ConflictError
            If nobody controls the rig.
        """
        _require_teacher(who, "change a controller's time limit")
        if not (math.isfinite(seconds) and abs(seconds) <= _MAX_EXTENSION):
            raise InvalidParameterError(
                f"seconds must be a finite number between {-_MAX_EXTENSION:g} and "
                f"{_MAX_EXTENSION:g}, got {seconds!r}"
            )

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            control = self._active(session, rig.id)
            if control is None:
                raise ConflictError(f"nobody controls rig {rig.id!r}; there is no limit to change")
            control.deadline = max(control.deadline + timedelta(seconds=seconds), now)
            if control.deadline <= now:
                self._end(
                    session, rig, control, TurnEndReason.TIME_LIMIT, now, now, by=who.username
                )

        return self._write(rig_id, who, act, heartbeat=False)[0]

    def kick(self, rig_id: str, who: Principal, username: str | None = None) -> RigView:
        """End a user's turn or queue place (default: the controller's turn).

        Raises
        ------
        AccessDeniedError
            If ``who`` is not a teacher.
        ConflictError
            If the named user neither controls the rig nor waits for it.
        """
        _require_teacher(who, "kick a user off a rig")

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            control = self._active(session, rig.id)
            name = username.strip().lower() if username is not None else None
            if name is None or (control is not None and control.username == name):
                if control is None:
                    raise ConflictError(f"nobody controls rig {rig.id!r}")
                self._end(session, rig, control, TurnEndReason.KICKED, now, now, by=who.username)
                return
            user_id = session.scalar(select(User.id).where(User.username == name))
            entry = None if user_id is None else self._waiting(session, rig.id, user_id)
            if entry is None:
                raise ConflictError(f"{username!r} neither controls nor waits for rig {rig.id!r}")
            entry.left_at = now
            entry.leave_reason = LeaveReason.KICKED.value

        return self._write(rig_id, who, act, heartbeat=False)[0]

    def set_service(self, rig_id: str, who: Principal, in_service: bool) -> RigView:
        """Take a rig out of service (its users are kicked) or back in; clears a fault.

        Raises
        ------
        AccessDeniedError
            If ``who`` is not a teacher.
        """
        _require_teacher(who, "take rigs in or out of service")

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            rig.fault = None
            rig.fault_at = None
            rig.in_service = in_service
            if in_service:
                return
            control = self._active(session, rig.id)
            if control is not None:
                self._end(session, rig, control, TurnEndReason.KICKED, now, now, by=who.username)
            for entry in self._queue(session, rig.id):
                entry.left_at = now
                entry.leave_reason = LeaveReason.KICKED.value

        return self._write(rig_id, who, act, heartbeat=False)[0]

    def history(
        self, rig_id: str | None = None, user_id: int | None = None
    ) -> list[ControlSession]:
        """Return control sessions, newest first, optionally of one rig and/or user."""
        query = select(ControlSession).order_by(
            ControlSession.started_at.desc(), ControlSession.id.desc()
        )
        if rig_id is not None:
            query = query.where(ControlSession.rig_id == rig_id)
        if user_id is not None:
            query = query.where(ControlSession.user_id == user_id)
        with self._db.read() as session:
            return list(session.scalars(query.limit(1000)))

    # -- the rig's side -------------------------------------------------------------------

    def report_fault(self, rig_id: str, message: str) -> None:
        """Latch a rig fault: the controller's turn ends (reason ``rig_fault``)."""
        if self.snapshot(rig_id).fault is not None:
            return

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            if rig.fault is not None:
                return
            rig.fault = message
            rig.fault_at = now
            control = self._active(session, rig.id)
            if control is not None:
                self._end(session, rig, control, TurnEndReason.RIG_FAULT, now, now)

        self._write(rig_id, None, act, heartbeat=False)

    def sweep(self) -> list[str]:
        """Apply every limit that has run out, on every rig; return the rigs that changed."""
        now = self._clock.now()
        changed = []
        for cfg in self._config.rigs:
            with self._db.read() as session:
                snap = self._snapshot(session, cfg.id)
            if self._due(snap, cfg, now):
                self._write(cfg.id, None, lambda s, rig, t: None, heartbeat=False)
                changed.append(cfg.id)
        return changed

    # -- the transaction ------------------------------------------------------------------

    def _write(
        self,
        rig_id: str,
        who: Principal | None,
        act: Callable[[Session, RigRow, datetime], None],
        *,
        heartbeat: bool = True,
    ) -> tuple[RigView, RigSnapshot]:
        cfg = self._config.rig(rig_id)
        if who is not None and heartbeat:
            # A teacher acting on a rig from the overview is not watching it.
            self._presence.touch(rig_id, who.username)
        failure: Exception | None = None
        with self._db.write() as session:
            rig = self._db.lock_rig(session, rig_id)
            now = self._clock.now()
            self._settle(session, rig, cfg, now)
            # An action refused (409, 403) must not undo the limits just applied, so
            # the refusal is raised after the commit. (Every action checks before it
            # changes anything.)
            try:
                act(session, rig, now)
            except (ConflictError, AccessDeniedError, InvalidParameterError) as exc:
                failure = exc
            if who is not None and heartbeat:
                self._touch(session, rig.id, who, now)
            self._advance(session, rig, cfg, now)
            rig.updated_at = now
            session.flush()
            snap = self._snapshot(session, rig_id)
        if self._on_change is not None:
            self._on_change(rig_id)
        if failure is not None:
            raise failure
        viewer = who if who is not None else _SYSTEM
        return self._render(snap, cfg, viewer, now), snap

    def _settle(self, session: Session, rig: RigRow, cfg: RigConfig, now: datetime) -> None:
        control = self._active(session, rig.id)
        if control is not None:
            due = self._end_due(control, cfg, now, run_active=self._run_active(session, rig.id))
            if due is not None:
                reason, at = due
                self._end(session, rig, control, reason, at, now)
        stale = session.scalars(_Q.stale, {"rig": rig.id, "seen": now - self._timeout})
        for entry in stale:
            entry.left_at = entry.last_heartbeat_at + self._timeout
            entry.leave_reason = LeaveReason.CLIENT_GONE.value
        self._advance(session, rig, cfg, now)

    def _advance(self, session: Session, rig: RigRow, cfg: RigConfig, now: datetime) -> None:
        """Move the rig on: finish a cool-down, hand control to the queue, power on or off."""
        session.flush()
        if not rig.in_service or rig.fault is not None:
            # Out of service or faulted: safe and unpowered until a teacher acts.
            self._set_power(rig, PowerState.OFF, now)
            rig.cooling_since = None
            rig.vacant_since = rig.vacant_since or now
            return
        power = PowerState(rig.power_state)
        if power is PowerState.COOLING and self._cooled(
            rig.id, rig.cooling_since, rig.ambient_output, cfg, now
        ):
            rig.needs_cooldown = False
            rig.cooling_since = None
            self._set_power(rig, PowerState.ON, now)
        if power is PowerState.ON and rig.ambient_output is None and not rig.needs_cooldown:
            reading = self._monitor.reading(rig.id)
            rig.ambient_output = reading[0] if reading is not None else None
        control = self._active(session, rig.id)
        head = self._head(session, rig.id)
        if control is None and head is not None and rig.fault is None:
            if PowerState(rig.power_state) is PowerState.OFF:
                if rig.needs_cooldown and cfg.cooldown.enabled:
                    rig.cooling_since = now
                    self._set_power(rig, PowerState.COOLING, now)
                else:
                    rig.needs_cooldown = False
                    self._set_power(rig, PowerState.ON, now)
            if PowerState(rig.power_state) is PowerState.ON:
                head.left_at = now
                head.leave_reason = LeaveReason.PROMOTED.value
                session.flush()
                user = session.get(User, head.user_id)
                session.add(
                    ControlSession(
                        rig_id=rig.id,
                        user_id=head.user_id,
                        username=user.username if user is not None else "?",
                        started_at=now,
                        deadline=now + timedelta(seconds=cfg.control_time_limit),
                        last_heartbeat_at=head.last_heartbeat_at,
                        last_activity_at=now,
                    )
                )
                session.flush()
                control = self._active(session, rig.id)
                head = self._head(session, rig.id)
        if control is None and head is None:
            if rig.vacant_since is None:
                rig.vacant_since = now
            elif (
                PowerState(rig.power_state) is not PowerState.OFF
                and (now - rig.vacant_since).total_seconds() >= cfg.power_off_grace
            ):
                rig.cooling_since = None
                self._set_power(rig, PowerState.OFF, now)
        else:
            rig.vacant_since = None

    def _end(
        self,
        session: Session,
        rig: RigRow,
        control: ControlSession,
        reason: TurnEndReason,
        at: datetime,
        now: datetime,
        *,
        by: str | None = None,
    ) -> None:
        control.ended_at = max(at, control.started_at)
        control.end_reason = reason.value
        control.ended_by = by
        session.flush()
        if self._cooldown(rig.id):
            rig.needs_cooldown = True
            if PowerState(rig.power_state) is PowerState.ON:
                rig.cooling_since = now
                self._set_power(rig, PowerState.COOLING, now)

    def _touch(self, session: Session, rig_id: str, who: Principal, now: datetime) -> None:
        control = self._active(session, rig_id)
        if control is not None and control.user_id == who.user_id:
            control.last_heartbeat_at = now
        entry = self._waiting(session, rig_id, who.user_id)
        if entry is not None:
            entry.last_heartbeat_at = now

    # -- rules ------------------------------------------------------------------------------

    def _end_due(
        self, control: ControlSession, cfg: RigConfig, now: datetime, *, run_active: bool
    ) -> tuple[TurnEndReason, datetime] | None:
        return _end_due(
            deadline=control.deadline,
            last_heartbeat=control.last_heartbeat_at,
            last_activity=control.last_activity_at,
            timeout=self._timeout,
            idle_limit=None if run_active else cfg.idle_limit,
            now=now,
        )

    def _due(self, snap: RigSnapshot, cfg: RigConfig, now: datetime) -> bool:
        """Whether a write would change the rig (limits run out, a hand-over pending...)."""
        c = snap.controller
        if c is not None and (
            _end_due(
                deadline=c.deadline,
                last_heartbeat=c.last_heartbeat_at,
                last_activity=c.last_activity_at,
                timeout=self._timeout,
                idle_limit=None if snap.run_active else cfg.idle_limit,
                now=now,
            )
            is not None
        ):
            return True
        if any(slot.last_heartbeat_at + self._timeout <= now for slot in snap.queue):
            return True
        if not snap.in_service or snap.fault is not None:
            return snap.power is not PowerState.OFF
        if snap.power is PowerState.COOLING and self._cooled(
            snap.id, snap.cooling_since, snap.ambient_output, cfg, now
        ):
            return True
        if c is None and snap.queue and snap.fault is None and snap.power is not PowerState.COOLING:
            return True
        if c is None and not snap.queue:
            if snap.vacant_since is None:
                return True
            grace_over = (now - snap.vacant_since).total_seconds() >= cfg.power_off_grace
            if snap.power is not PowerState.OFF and grace_over:
                return True
        # A first reading of a cold, powered rig is its ambient, to be recorded.
        return (
            snap.power is PowerState.ON
            and snap.ambient_output is None
            and not snap.needs_cooldown
            and self._monitor.reading(snap.id) is not None
        )

    def _heartbeat_stale(self, snap: RigSnapshot, who: Principal, now: datetime) -> bool:
        c = snap.controller
        if c is not None and c.user_id == who.user_id:
            return now - c.last_heartbeat_at >= _HEARTBEAT_WRITE_INTERVAL
        slot = snap.slot_of(who.user_id)
        return slot is not None and now - slot.last_heartbeat_at >= _HEARTBEAT_WRITE_INTERVAL

    def _cooldown(self, rig_id: str) -> bool:
        return any(rig.id == rig_id and rig.cooldown.enabled for rig in self._config.rigs)

    def _cooled(
        self,
        rig_id: str,
        cooling_since: datetime | None,
        measured_ambient: float | None,
        cfg: RigConfig,
        now: datetime,
    ) -> bool:
        if cooling_since is None:
            return True
        if (now - cooling_since).total_seconds() >= cfg.cooldown.max_seconds:
            return True
        ambient = cfg.cooldown.ambient if cfg.cooldown.ambient is not None else measured_ambient
        reading = self._monitor.reading(rig_id)
        # Only a reading taken during the cool-down says the rig has cooled.
        if reading is None or ambient is None or reading[1] <= cooling_since:
            return False
        return abs(reading[0] - ambient) <= cfg.cooldown.tolerance

    @staticmethod
    def _set_power(rig: RigRow, power: PowerState, now: datetime) -> None:
        if rig.power_state != power.value:
            rig.power_state = power.value
            rig.power_changed_at = now

    # -- queries ------------------------------------------------------------------------------
    # Built once (see _Q below): building a statement costs more than running it here.

    @staticmethod
    def _active(session: Session, rig_id: str) -> ControlSession | None:
        return session.scalars(_Q.active, {"rig": rig_id}).one_or_none()

    @staticmethod
    def _queue(session: Session, rig_id: str) -> list[QueueEntry]:
        return list(session.scalars(_Q.queue, {"rig": rig_id}))

    @staticmethod
    def _head(session: Session, rig_id: str) -> QueueEntry | None:
        return session.scalars(_Q.head, {"rig": rig_id}).first()

    @staticmethod
    def _waiting(session: Session, rig_id: str, user_id: int) -> QueueEntry | None:
        return session.scalars(_Q.waiting, {"rig": rig_id, "user": user_id}).one_or_none()

    @staticmethod
    def _run_active(session: Session, rig_id: str) -> bool:
        return session.scalar(_Q.run_active, {"rig": rig_id}) is not None

    def _snapshot(self, session: Session, rig_id: str) -> RigSnapshot:
        rig = session.get(RigRow, rig_id, populate_existing=True)
        if rig is None:
            # Configured but not yet in the table: start-up has not run.
            raise ConflictError(f"rig {rig_id!r} is not ready yet; the lab is starting")
        control = self._active(session, rig_id)
        # Plain rows, not ORM objects: a class-sized queue is read on every look at the rig.
        rows = session.execute(_Q.queue_rows, {"rig": rig_id}).all()
        queue = tuple(
            QueueSlot(user_id, name, ticket, i + 1, joined, seen)
            for i, (user_id, name, ticket, joined, seen) in enumerate(rows)
        )
        last_input = None
        if control is not None:
            last_input = session.scalar(_Q.last_input, {"control": control.id})
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
            ),
            queue=queue,
            run_active=self._run_active(session, rig_id),
            last_input=last_input,
        )

    # -- presentation ---------------------------------------------------------------------------

    def render(
        self, snap: RigSnapshot, who: Principal, watchers: list[Watcher] | None = None
    ) -> RigView:
        """Return ``snap`` as ``who`` sees it, now (no database access).

        ``watchers`` may be given when rendering one snapshot for many callers.
        """
        cfg = self._config.rig(snap.id)
        return self._render(snap, cfg, who, self._clock.now(), watchers)

    def _render(
        self,
        snap: RigSnapshot,
        cfg: RigConfig,
        who: Principal,
        now: datetime,
        watchers: list[Watcher] | None = None,
    ) -> RigView:
        if watchers is None:
            watchers = self._presence.watchers(snap.id)
        access = _access_view(snap, cfg, who, now, len(watchers))
        return RigView(
            id=snap.id,
            title=snap.title,
            kind=cfg.kind,
            state=_state_name(snap),
            in_service=snap.in_service,
            fault=snap.fault,
            published=self._monitor.published(snap.id),
            last_input=snap.last_input,
            config=cfg,
            client_timeout=self._timeout.total_seconds(),
            access=access,
            queue=snap.queue if who.is_teacher else None,
            watcher_list=tuple(watchers) if who.is_teacher else None,
            snapshot=snap,
        )


class _Q:
    """The statements of the hot path, with bound parameters."""

    _waiting = (QueueEntry.rig_id == bindparam("rig"), QueueEntry.left_at.is_(None))
    active = select(ControlSession).where(
        ControlSession.rig_id == bindparam("rig"), ControlSession.ended_at.is_(None)
    )
    queue = select(QueueEntry).where(*_waiting).order_by(QueueEntry.ticket)
    head = queue.limit(1)
    waiting = select(QueueEntry).where(*_waiting, QueueEntry.user_id == bindparam("user"))
    stale = select(QueueEntry).where(
        *_waiting, QueueEntry.last_heartbeat_at <= bindparam("seen", type_=UTCDateTime)
    )
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
    last_input = (
        select(Command.value)
        .where(Command.control_session_id == bindparam("control"), Command.kind == "input")
        .order_by(Command.at.desc(), Command.id.desc())
        .limit(1)
    )


# A principal for work the lab does on its own (sweeps, faults); sees what a teacher sees.
_SYSTEM = Principal(user_id=-1, username="(lab)", role=Role.TEACHER)


def _require_teacher(who: Principal, action: str) -> None:
    if not who.is_teacher:
        raise AccessDeniedError(f"only a teacher may {action}")


def _check_input(u: object, published: PublishedRig, rig_id: str) -> float:
    unit = published.input_unit
    allowed = f"[{published.input_min:g}, {published.input_max:g}] {unit}"
    if isinstance(u, bool) or not isinstance(u, int | float):
        raise InvalidParameterError(f"u must be a number in {allowed}, got {u!r}")
    value = float(u)
    if not math.isfinite(value):
        raise InvalidParameterError(f"u must be a finite number in {allowed}, got {value!r}")
    if not published.input_min <= value <= published.input_max:
        raise InvalidParameterError(
            f"u = {value:g} {unit} is outside the input range of rig {rig_id!r}: {allowed}"
        )
    return value


def _end_due(
    *,
    deadline: datetime,
    last_heartbeat: datetime,
    last_activity: datetime,
    timeout: timedelta,
    idle_limit: float | None,
    now: datetime,
) -> tuple[TurnEndReason, datetime] | None:
    # The earliest limit reached wins; on a tie the time limit is the reason given.
    candidates: list[tuple[datetime, TurnEndReason]] = [
        (deadline, TurnEndReason.TIME_LIMIT),
        (last_heartbeat + timeout, TurnEndReason.CLIENT_GONE),
    ]
    if idle_limit is not None:
        candidates.append((last_activity + timedelta(seconds=idle_limit), TurnEndReason.IDLE))
    at, reason = min(candidates, key=lambda c: c[0])
    return (reason, at) if at <= now else None


def _state_name(snap: RigSnapshot) -> RigStateName:
    if not snap.in_service:
        return "out_of_service"
    if snap.fault is not None:
        return "fault"
    if snap.power is PowerState.COOLING:
        return "cooldown"
    if snap.controller is not None:
        return "in_use"
    if snap.power is PowerState.OFF:
        return "off"
    return "free"


def _access_view(
    snap: RigSnapshot, cfg: RigConfig, who: Principal, now: datetime, watchers: int
) -> AccessView:
    c = snap.controller
    controllable = snap.in_service and snap.fault is None
    controller_name = c.username if c is not None else None
    if c is not None and c.user_id == who.user_id:
        idle_left = None
        if cfg.idle_limit is not None and not snap.run_active:
            idle_left = _seconds_until(c.last_activity_at + timedelta(seconds=cfg.idle_limit), now)
        return AccessView(
            role="controller",
            queue_size=len(snap.queue),
            queue_position=None,
            estimated_time_until_control=0.0,
            time_left=_seconds_until(c.deadline, now),
            idle_time_left=idle_left,
            controller=controller_name,
            watchers=watchers,
        )
    slot = snap.slot_of(who.user_id)
    position = slot.position if slot is not None else len(snap.queue) + 1
    eta = _eta(snap, cfg, position, now) if controllable else None
    return AccessView(
        role="queued" if slot is not None else "watcher",
        queue_size=len(snap.queue),
        queue_position=slot.position if slot is not None else None,
        estimated_time_until_control=eta,
        time_left=None if c is None else _seconds_until(c.deadline, now),
        idle_time_left=None,
        controller=controller_name,
        watchers=watchers,
    )


def _eta(snap: RigSnapshot, cfg: RigConfig, position: int, now: datetime) -> float:
    """Upper bound on the wait of queue place ``position``: every turn ahead runs in full."""
    cooldown = cfg.cooldown.max_seconds if cfg.cooldown.enabled else 0.0
    if snap.controller is not None:
        first = _seconds_until(snap.controller.deadline, now) + cooldown
    elif snap.power is PowerState.COOLING and snap.cooling_since is not None:
        first = max(0.0, cooldown - (now - snap.cooling_since).total_seconds())
    else:
        first = 0.0
    return first + (position - 1) * (cfg.control_time_limit + cooldown)


def _seconds_until(instant: datetime, now: datetime) -> float:
    return max(0.0, (instant - now).total_seconds())
