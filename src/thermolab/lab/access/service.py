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
from datetime import datetime, timedelta
from typing import TypeVar

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    ConflictError,
    InvalidParameterError,
    TurnExtensionRefusedError,
)
from thermolab.lab.access import queries as q
from thermolab.lab.access.extension import TURN_EXTENSION, extension_refusal
from thermolab.lab.access.rules import (
    TurnRules,
    end_turn,
    is_due,
    next_state,
)
from thermolab.lab.access.views import (
    CommandRecord,
    RigMonitor,
    RigSnapshot,
    RigView,
    render_view,
)
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
    TurnEndReason,
    User,
)
from thermolab.lab.devices import PublishedRig
from thermolab.lab.presence import Presence, Watcher
from thermolab.lab.users import Principal

__all__ = ["AccessService"]

T = TypeVar("T")

# A heartbeat is written at most this often per client, so that polling stays cheap.
_HEARTBEAT_WRITE_INTERVAL = timedelta(seconds=1)
_MAX_EXTENSION = 24 * 3600.0


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
            q.reset_for_startup(session, self._config, now)

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
            control = q.active(session, rig.id)
            if control is not None and control.user_id == who.user_id:
                return
            if q.waiting(session, rig.id, who.user_id) is not None:
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
            control = q.active(session, rig.id)
            if control is not None and control.user_id == who.user_id:
                self._end(session, rig, TurnEndReason.RELEASED, now, now)
                return
            entry = q.waiting(session, rig.id, who.user_id)
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
            control = q.active(session, rig.id)
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

    def extend_own(self, rig_id: str, who: Principal) -> RigView:
        """The controller's own extension of the turn (``access.extension``'s rules).

        Raises
        ------
        ConflictError
            If ``who`` does not control the rig.
        TurnExtensionRefusedError
            If someone waits, the turn is not in its last minute, or it was
            extended as far as allowed (the message says which).
        """

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            control = q.active(session, rig.id)
            if control is None or control.user_id != who.user_id:
                raise ConflictError(f"you do not control rig {rig.id!r}")
            snap = self._snapshot(session, rig.id)
            refusal = extension_refusal(
                queue_size=len(snap.queue),
                started_at=control.started_at,
                deadline=control.deadline,
                time_limit=self._config.rig(rig.id).control_time_limit,
                now=now,
            )
            if refusal is not None:
                raise TurnExtensionRefusedError(refusal)
            control.deadline += timedelta(seconds=TURN_EXTENSION)

        return self._write(rig_id, who, act)[0]

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
            control = q.active(session, rig.id)
            if control is None:
                raise ConflictError(f"nobody controls rig {rig.id!r}; there is no limit to change")
            control.deadline = max(control.deadline + timedelta(seconds=seconds), now)
            if control.deadline <= now:
                self._end(session, rig, TurnEndReason.TIME_LIMIT, now, now, by=who.username)

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
            control = q.active(session, rig.id)
            name = username.strip().lower() if username is not None else None
            if name is None or (control is not None and control.username == name):
                if control is None:
                    raise ConflictError(f"nobody controls rig {rig.id!r}")
                self._end(session, rig, TurnEndReason.KICKED, now, now, by=who.username)
                return
            user_id = session.scalar(select(User.id).where(User.username == name))
            entry = None if user_id is None else q.waiting(session, rig.id, user_id)
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
            control = q.active(session, rig.id)
            if control is not None:
                self._end(session, rig, TurnEndReason.KICKED, now, now, by=who.username)
            for entry in q.queue(session, rig.id):
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
            control = q.active(session, rig.id)
            if control is not None:
                self._end(session, rig, TurnEndReason.RIG_FAULT, now, now)

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
            self._settle(session, rig, cfg, now)
            rig.updated_at = now
            session.flush()
            snap = self._snapshot(session, rig_id)
        if self._on_change is not None:
            self._on_change(rig_id)
        if failure is not None:
            raise failure
        viewer = who if who is not None else _SYSTEM
        return self._render(snap, cfg, viewer, now), snap

    # -- the turn rules, applied ---------------------------------------------------------

    def _rules(self, cfg: RigConfig) -> TurnRules:
        return TurnRules.of(cfg, self._timeout)

    def _settle(self, session: Session, rig: RigRow, cfg: RigConfig, now: datetime) -> None:
        """Apply what the turn rules say happens now (limits, hand-over, power)."""
        before, control, entries = q.read_turn_state(session, rig)
        after = next_state(before, self._rules(cfg), now, self._monitor.reading(rig.id))
        q.write_transition(session, rig, control, entries, after, now)

    def _end(
        self,
        session: Session,
        rig: RigRow,
        reason: TurnEndReason,
        at: datetime,
        now: datetime,
        *,
        by: str | None = None,
    ) -> None:
        before, control, entries = q.read_turn_state(session, rig)
        after = end_turn(before, reason, at, self._rules(self._config.rig(rig.id)), now)
        q.write_transition(session, rig, control, entries, after, now, by=by)

    def _touch(self, session: Session, rig_id: str, who: Principal, now: datetime) -> None:
        control = q.active(session, rig_id)
        if control is not None and control.user_id == who.user_id:
            control.last_heartbeat_at = now
        entry = q.waiting(session, rig_id, who.user_id)
        if entry is not None:
            entry.last_heartbeat_at = now

    def _due(self, snap: RigSnapshot, cfg: RigConfig, now: datetime) -> bool:
        """Whether a write would change the rig (derived from the same transition table)."""
        return is_due(snap.turn_state(), self._rules(cfg), now, self._monitor.reading(snap.id))

    def _heartbeat_stale(self, snap: RigSnapshot, who: Principal, now: datetime) -> bool:
        c = snap.controller
        if c is not None and c.user_id == who.user_id:
            return now - c.last_heartbeat_at >= _HEARTBEAT_WRITE_INTERVAL
        slot = snap.slot_of(who.user_id)
        return slot is not None and now - slot.last_heartbeat_at >= _HEARTBEAT_WRITE_INTERVAL

    def _cooldown(self, rig_id: str) -> bool:
        return any(rig.id == rig_id and rig.cooldown.enabled for rig in self._config.rigs)

    @staticmethod
    def _set_power(rig: RigRow, power: PowerState, now: datetime) -> None:
        if rig.power_state != power.value:
            rig.power_state = power.value
            rig.power_changed_at = now

    def _snapshot(self, session: Session, rig_id: str) -> RigSnapshot:
        return q.read_snapshot(session, rig_id)

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
        published = self._monitor.published(snap.id)
        return render_view(snap, cfg, who, now, watchers, published, self._timeout)


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
