"""Who may do what with a rig: the paper's access model, made exact.

Any logged-in user may watch any rig. One user at a time controls a rig;
asking for control takes it if the rig is free, or joins a FIFO queue. A turn
ends when the controller releases it, when the rig's time limit runs out (a
teacher may extend or cut it), when the controller has given no command for
the idle limit, when their client has been silent for the client timeout, when
a teacher kicks them, or when the rig faults; the head of the queue then gets
control at once (after a cool-down if the rig is configured for one). Every
end is recorded with its reason.

Each action here is one locked transaction of
:class:`~thermolab.lab.access.transactions.RigTransactions` (how "exactly one
controller" holds under any interleaving is told there); the rules themselves
are the pure table of :mod:`thermolab.lab.access.rules`.
"""

from __future__ import annotations

import math
from dataclasses import replace
from datetime import datetime, timedelta

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import (
    ConflictError,
    FaultNotClearedError,
    InvalidParameterError,
    NobodyControlsError,
    NotControllerError,
    RigBookedError,
    RigOutOfServiceError,
    TurnExtensionRefusedError,
)
from thermolab.lab.access import queries as q
from thermolab.lab.access.extension import TURN_EXTENSION, extension_refusal
from thermolab.lab.access.rules import Slot, current_slot
from thermolab.lab.access.transactions import RigTransactions
from thermolab.lab.access.views import CommandRecord, RigView, turn_end_words, turn_limit
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.models import (
    Command,
    ControlSession,
    LeaveReason,
    QueueEntry,
    RigRow,
    TurnEndReason,
    User,
)
from thermolab.lab.rigs.devices import PublishedRig

__all__ = ["AccessService"]

_MAX_EXTENSION = 24 * 3600.0


class AccessService(RigTransactions):
    """The access model over the lab's database: the actions of users, teachers and rigs.

    Reading, rendering, the sweep and the locked transaction are
    :class:`~thermolab.lab.access.transactions.RigTransactions`'.
    """

    # -- the caller's own control ------------------------------------------------------

    def request_control(self, rig_id: str, who: Principal) -> RigView:
        """Take control of a free rig, or join its queue (idempotent).

        Raises
        ------
        NotFoundError
            If the lab has no such rig.
        ConflictError
            If the rig is out of service or faulted.
        RigBookedError
            If a slot of a course ``who`` is not in goes on.
        """

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            if not rig.in_service:
                raise RigOutOfServiceError(f"rig {rig.id!r} is out of service; ask a teacher")
            if rig.fault is not None:
                raise FaultNotClearedError(
                    f"rig {rig.id!r} has a fault ({rig.fault}); a teacher must clear it first"
                )
            control = q.active(session, rig.id)
            if control is not None and control.user_id == who.user_id:
                if who.token_id is not None:
                    control.token_id = who.token_id  # a script took over the user's turn
                return
            if q.waiting(session, rig.id, who.user_id) is not None:
                return
            _refuse_outsider(q.read_slots(session, rig.id, now, {who.user_id}), rig.id, who, now)
            ticket = rig.next_ticket
            rig.next_ticket = ticket + 1
            session.add(
                QueueEntry(
                    rig_id=rig.id,
                    user_id=who.user_id,
                    ticket=ticket,
                    joined_at=now,
                    last_heartbeat_at=now,
                    token_id=who.token_id,
                )
            )
            session.flush()

        return self._write(rig_id, who, act)

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

        return self._write(rig_id, who, act)

    def heartbeat(self, rig_id: str, who: Principal, language: str = "en") -> RigView:
        """Say the caller's client is still there; return the rig as they see it.

        To someone who does not control the rig the answer says how their last
        turn at it ended (``access.turn_ended``, in ``language``): a script's
        heartbeat is how it learns that its turn was ended from outside, and why.
        """
        view = self._write(rig_id, who, lambda s, rig, now: None)
        if view.access.role == "controller":
            return view
        with self._db.read() as session:
            ended = q.last_turn_end(session, rig_id, who.user_id)
        if ended is None:
            return view
        return replace(
            view, access=replace(view.access, turn_ended=turn_end_words(*ended, language))
        )

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

        with self.controlled(rig_id, who, "change its input") as turn:
            command = Command(
                rig_id=rig_id,
                control_session_id=turn.control.id,
                run_id=run_id,
                user_id=who.user_id,
                username=who.username,
                at=turn.now,
                kind="input",
                value=value,
                payload=None,
                applied=False,
            )
            turn.session.add(command)
            turn.session.flush()
            record = CommandRecord(command.id, rig_id, turn.control.id, value, turn.now)
        return record

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
                raise NotControllerError(f"you do not control rig {rig.id!r}")
            snap = q.read_snapshot(session, rig.id, now)
            refusal = extension_refusal(
                queue_size=len(snap.queue),
                started_at=control.started_at,
                deadline=control.deadline,
                time_limit=turn_limit(snap, self._config.rig(rig.id), now),
                now=now,
                script=control.token_id is not None,
            )
            if refusal is not None:
                raise TurnExtensionRefusedError(refusal)
            control.deadline += timedelta(seconds=TURN_EXTENSION)

        return self._write(rig_id, who, act)

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
        who.require_teacher("change a controller's time limit")
        if not (math.isfinite(seconds) and abs(seconds) <= _MAX_EXTENSION):
            raise InvalidParameterError(
                f"seconds must be a finite number between {-_MAX_EXTENSION:g} and "
                f"{_MAX_EXTENSION:g}, got {seconds!r}"
            )

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            control = q.active(session, rig.id)
            if control is None:
                raise NobodyControlsError(
                    f"nobody controls rig {rig.id!r}; there is no limit to change"
                )
            control.deadline = max(control.deadline + timedelta(seconds=seconds), now)
            if control.deadline <= now:
                self._end(session, rig, TurnEndReason.TIME_LIMIT, now, now, by=who.username)

        return self._write(rig_id, who, act, heartbeat=False)

    def kick(self, rig_id: str, who: Principal, username: str | None = None) -> RigView:
        """End a user's turn or queue place (default: the controller's turn).

        Raises
        ------
        AccessDeniedError
            If ``who`` is not a teacher.
        ConflictError
            If the named user neither controls the rig nor waits for it.
        """
        who.require_teacher("kick a user off a rig")

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            control = q.active(session, rig.id)
            name = username.strip().lower() if username is not None else None
            if name is None or (control is not None and control.username == name):
                if control is None:
                    raise NobodyControlsError(f"nobody controls rig {rig.id!r}")
                self._end(session, rig, TurnEndReason.KICKED, now, now, by=who.username)
                return
            user_id = session.scalar(select(User.id).where(User.username == name))
            entry = None if user_id is None else q.waiting(session, rig.id, user_id)
            if entry is None:
                raise ConflictError(
                    f"{username!r} neither controls nor waits for rig {rig.id!r}",
                    case="not_in_line",
                )
            entry.left_at = now
            entry.leave_reason = LeaveReason.KICKED.value

        return self._write(rig_id, who, act, heartbeat=False)

    def set_service(self, rig_id: str, who: Principal, in_service: bool) -> RigView:
        """Take a rig out of service (its users are kicked) or back in; clears a fault.

        Raises
        ------
        AccessDeniedError
            If ``who`` is not a teacher.
        """
        who.require_teacher("take rigs in or out of service")

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

        return self._write(rig_id, who, act, heartbeat=False)

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

    def end_token_turns(self, token_ids: frozenset[int]) -> None:
        """End the turns and queue places asked for with ``token_ids`` (revoked or expired).

        The script behind such a token can no longer reach the lab, so its turn
        ends as a silent client's does (reason ``client_gone``), but at once:
        the rig goes to its safe state now, not at the client timeout.
        """
        ids = list(token_ids)
        with self._db.read() as session:
            rigs = set(
                session.scalars(
                    select(ControlSession.rig_id).where(
                        ControlSession.token_id.in_(ids), ControlSession.ended_at.is_(None)
                    )
                )
            ) | set(
                session.scalars(
                    select(QueueEntry.rig_id).where(
                        QueueEntry.token_id.in_(ids), QueueEntry.left_at.is_(None)
                    )
                )
            )

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            control = q.active(session, rig.id)
            if control is not None and control.token_id in token_ids:
                self._end(session, rig, TurnEndReason.CLIENT_GONE, now, now)
            for entry in session.scalars(
                select(QueueEntry).where(
                    QueueEntry.rig_id == rig.id,
                    QueueEntry.token_id.in_(ids),
                    QueueEntry.left_at.is_(None),
                )
            ):
                entry.left_at = now
                entry.leave_reason = LeaveReason.CLIENT_GONE.value

        for rig_id in sorted(rigs):
            self._write(rig_id, None, act, heartbeat=False)

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

    def clear_healed_fault(self, rig_id: str, prefix: str) -> bool:
        """Clear the rig's fault if it is one that heals by itself (it starts with ``prefix``).

        The rig-host monitor's faults (offline, out of range) clear when the
        condition has passed; any other fault stays for a teacher.
        """

        def act(session: Session, rig: RigRow, now: datetime) -> None:
            if rig.fault is not None and rig.fault.startswith(prefix):
                rig.fault = None
                rig.fault_at = None

        fault = self.snapshot(rig_id).fault
        if fault is None or not fault.startswith(prefix):
            return False
        self._write(rig_id, None, act, heartbeat=False)
        return True


def _refuse_outsider(slots: tuple[Slot, ...], rig_id: str, who: Principal, now: datetime) -> None:
    """Refuse a place to someone outside the course whose slot goes on (the rules' own test)."""
    slot = current_slot(slots, now)
    if slot is None or slot.admits(who.user_id):
        return
    start, end = (f"{t:%Y-%m-%d %H:%M} UTC" for t in (slot.starts_at, slot.ends_at))
    raise RigBookedError(
        f"rig {rig_id!r} is booked for another course's slot from {start} to {end}; "
        "ask for control after it ends",
        {"startsAt": slot.starts_at.isoformat(), "endsAt": slot.ends_at.isoformat()},
    )


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
