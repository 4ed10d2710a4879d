"""The turn rules of a rig, as one pure transition table (no database, no clock).

:func:`next_state` takes a rig's :class:`TurnState`, its :class:`TurnRules`,
the time and the latest reading, and returns the state the rules move it to:
a turn whose limit has run out ends, silent queue places are dropped, a
cool-down finishes, the head of the queue gets control, a vacant rig powers
off after its grace. Both questions the service asks derive from it:

* what happens now — the service applies ``next_state`` to the stored rows;
* what is due next — :func:`is_due`: whether ``next_state`` would change
  anything (a look at a rig then needs a write).

So each rule is written once. Acts that end a turn themselves (release, kick,
fault) use :func:`end_turn`, the same rule ``next_state`` applies at a limit.

Bookings are part of the table: during a :class:`Slot` (a course's booking of
the rig) only the course's people may hold the turn or wait for it. At the
slot's start an outsider's turn ends (reason ``booked``, even while a run
samples: the run then ends with the turn) and outsiders' queue places are
dropped (``booked_out``); the queue goes on inside the slot. Outside slots
nothing changes.

Limits per course: a course may override the rig's turn limit, idle limit and
longest run (``COURSE_SETTINGS``). During the course's slot on a rig its values
(lowered by the rig's caps) are in force there (:meth:`TurnRules.during`);
outside slots the rig's. A turn's time limit is the one in force when it
started (its deadline is set then); the idle limit is read at every check.

Examples
--------
>>> from datetime import UTC, datetime, timedelta
>>> from thermolab.lab.config import CooldownPolicy
>>> t0 = datetime(2026, 1, 1, tzinfo=UTC)
>>> rules = TurnRules(timedelta(seconds=30), 300.0, None, 60.0, CooldownPolicy())
>>> free = TurnState(True, False, PowerState.ON, False, None, t0, 20.0, None, (), False)
>>> asking = replace(free, queue=(Waiting(7, t0),))
>>> after = next_state(asking, rules, t0, None)
>>> after.turn.user_id, after.turn.deadline - t0, after.queue
(7, datetime.timedelta(seconds=300), ())
>>> is_due(after, rules, t0 + timedelta(seconds=29), None)
False
>>> next_state(after, rules, t0 + timedelta(seconds=30), None).ended.reason.value
'client_gone'
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import datetime, timedelta

from thermolab.lab.config import CooldownPolicy, RigConfig
from thermolab.lab.config.teacher_settings import SettingValue, course_override
from thermolab.lab.db.models import PowerState, TurnEndReason

__all__ = [
    "Slot",
    "Turn",
    "TurnEnd",
    "TurnRules",
    "TurnState",
    "Waiting",
    "current_slot",
    "end_turn",
    "is_due",
    "limit_reached",
    "next_state",
    "queue_wait",
]

Reading = tuple[float, datetime]
"""A rig's output and when it was read."""


@dataclass(frozen=True, slots=True)
class Turn:
    """The controller's turn."""

    user_id: int | None
    started_at: datetime
    deadline: datetime
    last_heartbeat_at: datetime
    last_activity_at: datetime


@dataclass(frozen=True, slots=True)
class Waiting:
    """A queue place (the queue is kept in ticket order)."""

    user_id: int
    last_heartbeat_at: datetime


@dataclass(frozen=True, slots=True)
class TurnEnd:
    """How the last turn ended (set by the transition that ended it)."""

    reason: TurnEndReason
    at: datetime


@dataclass(frozen=True, slots=True)
class Slot:
    """A course's booking of the rig, ``[starts_at, ends_at)``.

    ``members`` holds the users at the rig (controller, queue) who belong to
    the course: the rules ask nothing of anyone else.
    """

    booking_id: int
    course_id: int
    starts_at: datetime
    ends_at: datetime
    members: frozenset[int] = frozenset()
    limits: tuple[tuple[str, SettingValue], ...] = ()
    """The course's overrides of the rig's limits (setting name, value), in force in the slot."""

    def admits(self, user_id: int | None) -> bool:
        """Whether ``user_id`` may hold or wait for a turn during the slot."""
        return user_id is not None and user_id in self.members


def current_slot(slots: tuple[Slot, ...], now: datetime) -> Slot | None:
    """The slot going on at ``now``, if any (slots of one rig never overlap)."""
    for slot in slots:
        if slot.starts_at <= now < slot.ends_at:
            return slot
    return None


@dataclass(frozen=True, slots=True)
class TurnState:
    """What the turn rules read and write of a rig."""

    in_service: bool
    faulted: bool
    power: PowerState
    needs_cooldown: bool
    cooling_since: datetime | None
    vacant_since: datetime | None
    ambient_output: float | None
    turn: Turn | None
    queue: tuple[Waiting, ...]
    run_active: bool
    ended: TurnEnd | None = None
    left: tuple[tuple[Waiting, datetime], ...] = ()
    """Queue places dropped by the transition (silent clients), with when."""
    slots: tuple[Slot, ...] = ()
    """The rig's bookings that have not ended (read with the state; never written)."""
    booked_out: tuple[tuple[Waiting, datetime], ...] = ()
    """Queue places dropped by the transition because a slot of another course goes on."""


@dataclass(frozen=True, slots=True)
class TurnRules:
    """A rig's limits, from its configuration and the lab's client timeout."""

    client_timeout: timedelta
    control_time_limit: float
    idle_limit: float | None
    power_off_grace: float
    cooldown: CooldownPolicy
    caps: tuple[tuple[str, float], ...] = ()
    """The technician's caps on the rig (a course's values are lowered to them)."""

    @classmethod
    def of(cls, cfg: RigConfig, client_timeout: timedelta) -> TurnRules:
        """The rules of a configured rig."""
        return cls(
            client_timeout,
            cfg.control_time_limit,
            cfg.idle_limit,
            cfg.power_off_grace,
            cfg.cooldown,
            cfg.caps,
        )

    def during(self, slot: Slot | None) -> TurnRules:
        """The rules in force during ``slot`` (``None``: outside slots, the rig's own).

        >>> from thermolab.lab.config import CooldownPolicy
        >>> t = datetime(2026, 1, 1)
        >>> rig = TurnRules(timedelta(seconds=30), 300.0, 60.0, 60.0, CooldownPolicy(),
        ...                 (("control_time_limit", 600.0),))
        >>> slot = Slot(1, 1, t, t, limits=(("control_time_limit", 900.0), ("idle_limit", None)))
        >>> r = rig.during(slot)
        >>> r.control_time_limit, r.idle_limit, rig.during(None) is rig
        (600.0, None, True)
        """
        if slot is None or not slot.limits:
            return self
        caps = dict(self.caps)
        given = {name: course_override(value, caps.get(name)) for name, value in slot.limits}
        limit = given.get("control_time_limit", self.control_time_limit)
        idle = given.get("idle_limit", self.idle_limit)
        assert isinstance(limit, int | float)
        assert idle is None or isinstance(idle, int | float)
        return replace(
            self,
            control_time_limit=float(limit),
            idle_limit=None if idle is None else float(idle),
        )


def limit_reached(
    turn: Turn, rules: TurnRules, now: datetime, *, run_active: bool
) -> TurnEnd | None:
    """The limit that ended ``turn`` by ``now``, dated when it was reached, if any.

    The earliest limit wins; on a tie the time limit is the reason given.
    While a run samples, the turn covers it: neither the time limit nor the
    idle limit applies (a started run is never cut because the turn's time ran
    out; START refuses a run longer than the rig's ``max_run_seconds``). The
    turn ends at the first transition after the run, if its time is up.
    """
    candidates: list[tuple[datetime, TurnEndReason]] = [
        (turn.last_heartbeat_at + rules.client_timeout, TurnEndReason.CLIENT_GONE),
    ]
    if not run_active:
        candidates.insert(0, (turn.deadline, TurnEndReason.TIME_LIMIT))
    if rules.idle_limit is not None and not run_active:
        idle_at = turn.last_activity_at + timedelta(seconds=rules.idle_limit)
        candidates.append((idle_at, TurnEndReason.IDLE))
    at, reason = min(candidates, key=lambda c: c[0])
    return TurnEnd(reason, max(at, turn.started_at)) if at <= now else None


def queue_wait(
    turn_left: float | None,
    run_left: float | None,
    cooling_left: float,
    position: int,
    rules: TurnRules,
) -> float:
    """Upper bound on the wait, in seconds, of queue place ``position`` (from 1).

    The current turn lasts until its time is up or, when a run goes longer,
    until the run ends (the run covers the turn); then the rig cools down (if
    it does) and every turn ahead runs in full.

    Parameters
    ----------
    turn_left : float or None
        Seconds until the current turn's time limit (``None``: nobody controls).
    run_left : float or None
        Seconds until the current run's planned end (``None``: no run).
    cooling_left : float
        Seconds the rig may still cool when nobody controls it.
    position : int
    rules : TurnRules

    Examples
    --------
    >>> from thermolab.lab.config import CooldownPolicy
    >>> rules = TurnRules(timedelta(seconds=30), 300.0, None, 60.0, CooldownPolicy())
    >>> queue_wait(100.0, None, 0.0, 2, rules), queue_wait(100.0, 1900.0, 0.0, 1, rules)
    (400.0, 1900.0)
    """
    cooldown = rules.cooldown.max_seconds if rules.cooldown.enabled else 0.0
    # Nobody controls: only a cool-down may stand before the head of the queue.
    first = cooling_left if turn_left is None else max(turn_left, run_left or 0.0) + cooldown
    return first + (position - 1) * (rules.control_time_limit + cooldown)


def end_turn(
    state: TurnState, reason: TurnEndReason, at: datetime, rules: TurnRules, now: datetime
) -> TurnState:
    """End the current turn: a rig with a cool-down starts cooling if it is on."""
    if state.turn is None:
        return state
    out = replace(state, turn=None, ended=TurnEnd(reason, max(at, state.turn.started_at)))
    if rules.cooldown.enabled:
        out = replace(out, needs_cooldown=True)
        if out.power is PowerState.ON:
            out = replace(out, cooling_since=now, power=PowerState.COOLING)
    return out


def cooled(state: TurnState, rules: TurnRules, now: datetime, reading: Reading | None) -> bool:
    """Whether a cooling rig is back at its ambient (or has cooled for the longest allowed)."""
    if state.cooling_since is None:
        return True
    if (now - state.cooling_since).total_seconds() >= rules.cooldown.max_seconds:
        return True
    configured = rules.cooldown.ambient
    ambient = configured if configured is not None else state.ambient_output
    # Only a reading taken during the cool-down says the rig has cooled.
    if reading is None or ambient is None or reading[1] <= state.cooling_since:
        return False
    return abs(reading[0] - ambient) <= rules.cooldown.tolerance


def next_state(
    state: TurnState, rules: TurnRules, now: datetime, reading: Reading | None
) -> TurnState:
    """The state the turn rules move ``state`` to at ``now`` (the transition table).

    ``ended`` and ``left`` of the result say which turn ended and which queue
    places were dropped by this transition.
    """
    s = replace(state, ended=None, left=(), booked_out=())
    # The limits in force now: a course's during its slot, else the rig's.
    rules = rules.during(current_slot(s.slots, now))
    # Limits: the turn, then queue places whose client fell silent.
    if s.turn is not None:
        end = limit_reached(s.turn, rules, now, run_active=s.run_active)
        if end is not None:
            s = end_turn(s, end.reason, end.at, rules, now)
    # A slot going on: outsiders lose the turn (even mid-run) and their queue places.
    slot = current_slot(s.slots, now)
    if slot is not None and s.turn is not None and not slot.admits(s.turn.user_id):
        s = end_turn(s, TurnEndReason.BOOKED, slot.starts_at, rules, now)
    if slot is not None and any(not slot.admits(w.user_id) for w in s.queue):
        s = replace(
            s,
            queue=tuple(w for w in s.queue if slot.admits(w.user_id)),
            booked_out=tuple((w, now) for w in s.queue if not slot.admits(w.user_id)),
        )
    gone = tuple(w for w in s.queue if w.last_heartbeat_at + rules.client_timeout <= now)
    if gone:
        s = replace(
            s,
            queue=tuple(w for w in s.queue if w not in gone),
            left=tuple((w, w.last_heartbeat_at + rules.client_timeout) for w in gone),
        )
    # Out of service or faulted: safe and unpowered until a teacher acts.
    if not s.in_service or s.faulted:
        return replace(
            s,
            power=PowerState.OFF,
            cooling_since=None,
            vacant_since=s.vacant_since or now,
        )
    power = s.power
    if power is PowerState.COOLING and cooled(s, rules, now, reading):
        s = replace(s, needs_cooldown=False, cooling_since=None, power=PowerState.ON)
    # A first reading of a cold, powered rig is its ambient.
    if power is PowerState.ON and s.ambient_output is None and not s.needs_cooldown:
        s = replace(s, ambient_output=reading[0] if reading is not None else None)
    if s.turn is None and s.queue:
        if s.power is PowerState.OFF:
            if s.needs_cooldown and rules.cooldown.enabled:
                s = replace(s, cooling_since=now, power=PowerState.COOLING)
            else:
                s = replace(s, needs_cooldown=False, power=PowerState.ON)
        if s.power is PowerState.ON:
            head = s.queue[0]
            turn = Turn(
                user_id=head.user_id,
                started_at=now,
                deadline=now + timedelta(seconds=rules.control_time_limit),
                last_heartbeat_at=head.last_heartbeat_at,
                last_activity_at=now,
            )
            s = replace(s, turn=turn, queue=s.queue[1:])
    if s.turn is None and not s.queue:
        if s.vacant_since is None:
            s = replace(s, vacant_since=now)
        elif (
            s.power is not PowerState.OFF
            and (now - s.vacant_since).total_seconds() >= rules.power_off_grace
        ):
            s = replace(s, cooling_since=None, power=PowerState.OFF)
    else:
        s = replace(s, vacant_since=None)
    return s


def is_due(state: TurnState, rules: TurnRules, now: datetime, reading: Reading | None) -> bool:
    """Whether the turn rules would change ``state`` at ``now`` (a write is due)."""
    return next_state(state, rules, now, reading) != replace(
        state, ended=None, left=(), booked_out=()
    )
