"""The access model's one transaction: the rig locked, the turn rules applied, the change told.

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

Inside the lock, what happens now is :func:`~thermolab.lab.access.rules.next_state`
(limits, hand-over, power), applied before and after the action; whether a
look at a rig must write is :func:`~thermolab.lab.access.rules.is_due`, the
same table. Time comes from an injected :class:`~thermolab.lab.clock.LabClock`;
limits are checked whenever the rig is looked at (any request) and by the
lab's periodic sweep, and an end is dated at the instant the limit was
reached, so the record does not depend on when the check ran.
:class:`RigTransactions` also reads and renders rigs and gives the
controller their turn's transaction (:meth:`RigTransactions.controlled`, what START
and an input use); the other actions are
:class:`thermolab.lab.access.service.AccessService`'s.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    ConflictError,
    InvalidParameterError,
    TurnEndedError,
)
from thermolab.lab.access import queries as q
from thermolab.lab.access.rules import TurnRules, current_slot, end_turn, is_due, next_state
from thermolab.lab.access.views import (
    RigMonitor,
    RigSnapshot,
    RigView,
    render_view,
    turn_end_words,
)
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig, RigConfig
from thermolab.lab.config.teacher_settings import SettingValue
from thermolab.lab.db import Database
from thermolab.lab.db.models import ControlSession, PowerState, RigRow, Role, TurnEndReason
from thermolab.lab.live.presence import Presence, Watcher

__all__ = ["Controlled", "LockedRig", "RigTransactions"]

# A heartbeat is written at most this often per client, so that polling stays cheap.
_HEARTBEAT_WRITE_INTERVAL = timedelta(seconds=1)


@dataclass(slots=True)
class LockedRig:
    """A rig inside its locked transaction: what an action works on.

    ``snapshot`` is the rig read back after the action (``None`` when the
    transaction was asked not to read it back).
    """

    session: Session
    rig: RigRow
    now: datetime
    snapshot: RigSnapshot | None = None


@dataclass(frozen=True, slots=True)
class Controlled:
    """The controller's turn inside the rig's locked transaction.

    What :meth:`RigTransactions.controlled` yields.
    """

    session: Session
    rig: RigRow
    control: ControlSession
    now: datetime

    def course_limits(self) -> tuple[tuple[str, SettingValue], ...]:
        """The limits a course's slot going on now sets on the rig (empty: the rig's own)."""
        slot = current_slot(q.read_slots(self.session, self.rig.id, self.now, set()), self.now)
        return () if slot is None else slot.limits


class RigTransactions:
    """The turn rules applied over the lab's database, one locked transaction per decision.

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
        now = self._clock.now()
        with self._db.read() as session:
            return q.read_snapshot(session, rig_id, now)

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

    def caller_turn(self, rig_id: str, user_id: int) -> int | None:
        """The id of ``user_id``'s live turn at the rig, if they have the controls now."""
        with self._db.read() as session:
            turn: int | None = session.scalar(
                select(ControlSession.id).where(
                    ControlSession.rig_id == rig_id,
                    ControlSession.user_id == user_id,
                    ControlSession.ended_at.is_(None),
                )
            )
        return turn

    def turn_ended_error(self, rig_id: str, turn: int) -> TurnEndedError:
        """The 409 of an action whose turn ``turn`` ended while it was being decided.

        An action that arrived during the caller's turn and finds, in its
        transaction, that the turn has ended lost a race: it gets 409
        ``turn_ended`` naming how the turn ended, not the 403 of someone who
        never had the controls.
        """
        with self._db.read() as session:
            reason = session.scalar(
                select(ControlSession.end_reason).where(ControlSession.id == turn)
            )
        how = f" ({reason})" if reason else ""
        return TurnEndedError(
            f"your turn at the controls of rig {rig_id!r} ended{how} while this START was "
            "being decided; no run was started"
        )

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
            snap = q.read_snapshot(session, rig_id, now)
        if self._due(snap, cfg, now) or (heartbeat and self._heartbeat_stale(snap, who, now)):
            return self._write(rig_id, who, lambda s, rig, t: None, heartbeat=heartbeat)
        return self._render(snap, cfg, who, now)

    def views(self, who: Principal) -> list[RigView]:
        """Return every configured rig as ``who`` sees it (no heartbeat, and not watching)."""
        return [self.view(rig.id, who, heartbeat=False) for rig in self._config.rigs]

    def sweep(self) -> list[str]:
        """Apply every limit that has run out, on every rig; return the rigs that changed."""
        now = self._clock.now()
        changed = []
        for rig in self._config.rigs:
            cfg = self._config.rig(rig.id)  # the teacher settings in force
            with self._db.read() as session:
                snap = q.read_snapshot(session, cfg.id, now)
            if self._due(snap, cfg, now):
                with self._locked(cfg.id, None, heartbeat=False, read_back=False):
                    pass
                changed.append(cfg.id)
        return changed

    # -- the transaction ------------------------------------------------------------------

    @contextmanager
    def _locked(
        self, rig_id: str, who: Principal | None, *, heartbeat: bool = True, read_back: bool = True
    ) -> Iterator[LockedRig]:
        """The rig's locked transaction: the rules applied before and after the body.

        A refusal the body raises (409, 403, 422) must not undo the limits just
        applied, so it is raised after the commit (every action checks before it
        changes anything); any other error rolls the transaction back.
        """
        cfg = self._config.rig(rig_id)
        if who is not None and heartbeat:
            # A teacher acting on a rig from the overview is not watching it.
            self._presence.touch(rig_id, who.username)
        failure: Exception | None = None
        with self._db.write() as session:
            rig = self._db.lock_rig(session, rig_id)
            locked = LockedRig(session, rig, self._clock.now())
            self._settle(session, rig, cfg, locked.now)
            try:
                yield locked
            except (ConflictError, AccessDeniedError, InvalidParameterError) as exc:
                failure = exc
            if who is not None and heartbeat:
                self._touch(session, rig.id, who, locked.now)
            self._settle(session, rig, cfg, locked.now)
            rig.updated_at = locked.now
            session.flush()
            if read_back:
                locked.snapshot = q.read_snapshot(session, rig_id, locked.now)
        if self._on_change is not None:
            self._on_change(rig_id)
        if failure is not None:
            raise failure

    def _write(
        self,
        rig_id: str,
        who: Principal | None,
        act: Callable[[Session, RigRow, datetime], None],
        *,
        heartbeat: bool = True,
    ) -> RigView:
        """Run ``act`` in the rig's locked transaction; return the rig as ``who`` sees it."""
        with self._locked(rig_id, who, heartbeat=heartbeat) as locked:
            act(locked.session, locked.rig, locked.now)
        assert locked.snapshot is not None
        viewer = who if who is not None else _SYSTEM
        return self._render(locked.snapshot, self._config.rig(rig_id), viewer, locked.now)

    @contextmanager
    def controlled(self, rig_id: str, who: Principal, action: str) -> Iterator[Controlled]:
        """The rig's locked transaction, entered only if ``who`` controls the rig.

        The turn counts as active (the idle limit restarts). The body must check
        before it changes anything: a refusal it raises (409, 403, 422) is
        raised after the commit of the limits applied meanwhile.

        Raises
        ------
        AccessDeniedError
            If ``who`` does not control the rig (the message says ``action``).
        """
        with self._locked(rig_id, who, read_back=False) as locked:
            control = q.active(locked.session, rig_id)
            if control is None or control.user_id != who.user_id:
                holder = "nobody" if control is None else "another user"
                # A script whose turn was ended from outside learns why from its next call.
                ended = q.last_turn_end(locked.session, rig_id, who.user_id)
                why = f"; your last turn at it ended: {turn_end_words(*ended)}" if ended else ""
                raise AccessDeniedError(
                    f"only the controller of rig {rig_id!r} may {action}, and "
                    f"{holder} controls it now{why}; ask for control first"
                )
            control.last_activity_at = locked.now
            yield Controlled(locked.session, locked.rig, control, locked.now)

    # -- the turn rules, applied ---------------------------------------------------------

    def _rules(self, cfg: RigConfig) -> TurnRules:
        return TurnRules.of(cfg, self._timeout)

    def _settle(self, session: Session, rig: RigRow, cfg: RigConfig, now: datetime) -> None:
        """Apply what the turn rules say happens now (limits, hand-over, power)."""
        before, control, entries = q.read_turn_state(session, rig, now)
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
        before, control, entries = q.read_turn_state(session, rig, now)
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
