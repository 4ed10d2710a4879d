"""What a rig's access state looks like: snapshots read in one transaction, and each user's view.

Pure presentation: :func:`render_access` and :func:`state_name` read a
:class:`RigSnapshot` and the time; they change nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Literal, Protocol

from thermolab.lab.access.extension import extension_refusal
from thermolab.lab.access.rules import (
    Slot,
    Turn,
    TurnRules,
    TurnState,
    Waiting,
    current_slot,
    queue_wait,
)
from thermolab.lab.accounts.users import Principal
from thermolab.lab.config import RigConfig
from thermolab.lab.config.teacher_settings import course_override, with_values
from thermolab.lab.db.models import PowerState, TurnEndReason
from thermolab.lab.error_messages import translate
from thermolab.lab.live.presence import Watcher
from thermolab.lab.rigs.devices import PublishedRig

__all__ = [
    "TURN_END_WORDS",
    "AccessRole",
    "AccessView",
    "CommandRecord",
    "ControlRecord",
    "QueueSlot",
    "RigMonitor",
    "RigSnapshot",
    "RigStateName",
    "RigView",
    "render_access",
    "render_view",
    "state_name",
    "turn_end_words",
]

AccessRole = Literal["controller", "queued", "watcher"]
RigStateName = Literal["off", "starting", "free", "in_use", "cooldown", "fault", "out_of_service"]


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
    script: bool = False  # asked for with an API token: extended without a ceiling


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
    run_ends_at: datetime | None = None
    """The planned end of the run going, if any (the queue's estimate counts it)."""
    slots: tuple[Slot, ...] = ()
    """The rig's current and next booked slot (the turn rules read them)."""

    def turn_state(self) -> TurnState:
        """The part of the snapshot the turn rules read."""
        c = self.controller
        return TurnState(
            in_service=self.in_service,
            faulted=self.fault is not None,
            power=self.power,
            needs_cooldown=self.needs_cooldown,
            cooling_since=self.cooling_since,
            vacant_since=self.vacant_since,
            ambient_output=self.ambient_output,
            turn=None
            if c is None
            else Turn(c.user_id, c.started_at, c.deadline, c.last_heartbeat_at, c.last_activity_at),
            queue=tuple(Waiting(s.user_id, s.last_heartbeat_at) for s in self.queue),
            run_active=self.run_active,
            slots=self.slots,
        )

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
    can_extend : bool
        Whether the controller may extend the turn now (``access.extension``);
        ``False`` for everyone else.
    turn_ended : str or None
        Answering a heartbeat of someone who does not control the rig: how
        their last turn at it ended, in words (:func:`turn_end_words`), so a
        script told its turn is over can say why.
    """

    role: AccessRole
    queue_size: int
    queue_position: int | None
    estimated_time_until_control: float | None
    time_left: float | None
    idle_time_left: float | None
    controller: str | None
    watchers: int
    can_extend: bool = False
    turn_ended: str | None = None


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


def state_name(snap: RigSnapshot) -> RigStateName:
    """The rig's state as the API names it."""
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


def render_access(
    snap: RigSnapshot, cfg: RigConfig, who: Principal, now: datetime, watchers: int
) -> AccessView:
    """The access part of the rig as ``who`` sees it at ``now``."""
    c = snap.controller
    controllable = snap.in_service and snap.fault is None
    controller_name = c.username if c is not None else None
    # The limits in force now (a course's during its slot); the client timeout plays no part.
    rules = TurnRules.of(cfg, timedelta(0)).during(current_slot(snap.slots, now))
    if c is not None and c.user_id == who.user_id:
        idle_left = None
        if rules.idle_limit is not None and not snap.run_active:
            idle_at = c.last_activity_at + timedelta(seconds=rules.idle_limit)
            idle_left = _seconds_until(idle_at, now)
        return AccessView(
            role="controller",
            queue_size=len(snap.queue),
            queue_position=None,
            estimated_time_until_control=0.0,
            time_left=_seconds_until(c.deadline, now),
            idle_time_left=idle_left,
            controller=controller_name,
            watchers=watchers,
            can_extend=extension_refusal(
                queue_size=len(snap.queue),
                started_at=c.started_at,
                deadline=c.deadline,
                time_limit=rules.control_time_limit,
                now=now,
                script=c.script,
            )
            is None,
        )
    slot = snap.slot_of(who.user_id)
    position = slot.position if slot is not None else len(snap.queue) + 1
    eta = _eta(snap, rules, position, now) if controllable else None
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


_END_WORDS = {
    TurnEndReason.RELEASED: "it was released",
    TurnEndReason.TIME_LIMIT: (
        "its time limit ran out (a turn is extended only while nobody waits for the rig)"
    ),
    TurnEndReason.IDLE: "it was idle for longer than the rig's idle limit",
    TurnEndReason.CLIENT_GONE: (
        "the lab heard nothing from its client within the client timeout, "
        "or its API token was revoked or expired"
    ),
    TurnEndReason.KICKED: "a teacher ended it",
    TurnEndReason.RIG_FAULT: "the rig reported a fault",
    TurnEndReason.SERVER_RESTART: "the lab restarted",
    TurnEndReason.BOOKED: "a course's booked slot on the rig began",
}
_KICKED_BY = "a teacher ({by}) ended it"
_CUT_BY = "a teacher ({by}) cut its time"  # a teacher's extension to now or earlier

#: Every way a turn's end is told (msgids of the server's catalogue, locale/).
TURN_END_WORDS = (*_END_WORDS.values(), _KICKED_BY, _CUT_BY)


def turn_end_words(reason: str, by: str | None, language: str = "en") -> str:
    """How a turn ended, in a user's words, in ``language``.

    A script learns it from its heartbeat's answer and shows it to the student
    who ran it, so it speaks the language the script's request asked for.

    Examples
    --------
    >>> turn_end_words("kicked", "tina")
    'a teacher (tina) ended it'
    >>> turn_end_words("time_limit", None)[:26]
    'its time limit ran out (a '
    >>> turn_end_words("kicked", "tina", "pt-BR")
    'um professor (tina) a encerrou'
    """
    if reason == TurnEndReason.KICKED and by:
        return translate(_KICKED_BY, language).format(by=by)
    if reason == TurnEndReason.TIME_LIMIT and by:
        return translate(_CUT_BY, language).format(by=by)
    words = _END_WORDS.get(TurnEndReason(reason))
    return reason if words is None else translate(words, language)


def in_force(cfg: RigConfig, snap: RigSnapshot, now: datetime) -> RigConfig:
    """The rig with the limits in force at ``now``: a course's during its slot, else its own."""
    slot = current_slot(snap.slots, now)
    if slot is None or not slot.limits:
        return cfg
    caps = dict(cfg.caps)
    return with_values(cfg, {n: course_override(v, caps.get(n)) for n, v in slot.limits})


def turn_limit(snap: RigSnapshot, cfg: RigConfig, now: datetime) -> float:
    """The turn limit in force at ``now`` (a course's during its slot), which bounds extensions."""
    rules = TurnRules.of(cfg, timedelta(0))
    return rules.during(current_slot(snap.slots, now)).control_time_limit


def _eta(snap: RigSnapshot, rules: TurnRules, position: int, now: datetime) -> float:
    """Upper bound on the wait of queue place ``position`` (:func:`.rules.queue_wait`)."""
    cooldown = rules.cooldown.max_seconds if rules.cooldown.enabled else 0.0
    turn_left = None if snap.controller is None else _seconds_until(snap.controller.deadline, now)
    run_left = None if snap.run_ends_at is None else _seconds_until(snap.run_ends_at, now)
    cooling_left = 0.0
    if snap.power is PowerState.COOLING and snap.cooling_since is not None:
        cooling_left = max(0.0, cooldown - (now - snap.cooling_since).total_seconds())
    return queue_wait(turn_left, run_left, cooling_left, position, rules)


def _seconds_until(instant: datetime, now: datetime) -> float:
    return max(0.0, (instant - now).total_seconds())


def render_view(
    snap: RigSnapshot,
    cfg: RigConfig,
    who: Principal,
    now: datetime,
    watchers: list[Watcher],
    published: PublishedRig,
    client_timeout: timedelta,
) -> RigView:
    """The rig as ``who`` sees it at ``now`` (queue and watchers for teachers only)."""
    return RigView(
        id=snap.id,
        title=snap.title,
        kind=cfg.kind,
        state=state_name(snap),
        in_service=snap.in_service,
        fault=snap.fault,
        published=published,
        last_input=snap.last_input,
        config=in_force(cfg, snap, now),
        client_timeout=client_timeout.total_seconds(),
        access=render_access(snap, cfg, who, now, len(watchers)),
        queue=snap.queue if who.is_teacher else None,
        watcher_list=tuple(watchers) if who.is_teacher else None,
        snapshot=snap,
    )
