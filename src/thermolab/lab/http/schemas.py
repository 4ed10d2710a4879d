"""JSON bodies of the lab's HTTP API (pydantic models, camelCase on the wire).

Request bodies refuse unknown fields and values of the wrong type, so a typo
is a 422 naming the field rather than a silently ignored setting (the base
models are :mod:`.bodies`). A run's bodies are beside its routes, in
:mod:`.routers.runs`.
"""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime
from typing import Annotated, Literal

from pydantic import Field

from thermolab.lab.access import QueueSlot, RigView
from thermolab.lab.accounts.security import MAX_PASSWORD_LENGTH, MIN_PASSWORD_LENGTH
from thermolab.lab.accounts.users import Principal, UserInfo
from thermolab.lab.db.models import ControlSession
from thermolab.lab.http.bodies import In as _In
from thermolab.lab.http.bodies import Out as _Out
from thermolab.lab.live.presence import Watcher
from thermolab.lab.service import InputResult

__all__ = [
    "AccessOut",
    "ActuatorOut",
    "ControlSessionOut",
    "CooldownOut",
    "CredentialsIn",
    "ErrorOut",
    "ExtendIn",
    "FurtherOutputOut",
    "InputIn",
    "InputOut",
    "InputRangeOut",
    "KickIn",
    "LimitsOut",
    "NewUserIn",
    "PasswordIn",
    "ProblemOut",
    "QueueSlotOut",
    "RigOut",
    "ServiceIn",
    "SessionOut",
    "UserOut",
    "ValidationErrorOut",
    "WatcherOut",
    "people_named",
]


# -- errors --------------------------------------------------------------------------------


class ErrorOut(_Out):
    """Every 4xx answer: ``detail`` says what was wrong and what is allowed; ``code`` is stable."""

    detail: str
    code: str = Field(
        description="stable name of the error: not_authenticated, access_denied, "
        "cross_origin, not_found, method_not_allowed, conflict, turn_ended, run_in_progress, "
        "previous_run_ending, rig_unavailable, body_too_large, rate_limited, "
        "camera_unavailable..."
    )
    message: str | None = Field(
        default=None,
        description="the code's sentence in the reader's language (the thermolab_lang cookie, "
        "else Accept-Language; Content-Language names it)",
    )


class ProblemOut(_Out):
    """One problem of a request that was refused with 422."""

    loc: list[str] = Field(
        description="where: ['body', field...], ['path', name], ['query', name]; "
        "empty when the problem is the settings together"
    )
    type: str = Field(description="pydantic's error type, or the error's code")
    msg: str
    params: dict[str, str | int] | None = Field(
        None, description="a class list's problem: the values its sentence names"
    )
    message: str | None = Field(None, description="a class list's problem in the reader's language")


class ValidationErrorOut(_Out):
    """Every 422 (a body, path or query value the API refuses): ``detail`` in words,
    ``errors`` one per problem."""

    detail: str
    code: Literal[
        "invalid_request",
        "invalid_parameter",
        "class_list_invalid",
        "gain_out_of_range",
        "setpoint_out_of_range",
        "setpoint_no_step",
        "no_output_unit",
        "setting_out_of_range",
        "image_invalid",
        "image_too_many_pixels",
        "setting_not_for_rig",
        "speedup_refused",
        "channel_not_on_rig",
        "pair_channel_unknown",
        "pair_wrong_role",
        "slot_ends_before_start",
        "slot_too_long",
        "slot_zone_missing",
        "time_zone_unknown",
    ] = Field(
        description="invalid_request: the request does not match the schema (a body that is "
        "not UTF-8 JSON included); invalid_parameter: the values match the schema but the lab "
        "refuses them (a signal outside the rig's range, a run too long...); "
        "class_list_invalid: a class list with bad lines (one entry of errors per line); "
        "gain_out_of_range, setpoint_out_of_range, setpoint_no_step, no_output_unit: the "
        "closed loop's refusals; "
        "setting_out_of_range: a teacher setting outside the rig's allowed range (the message "
        "names the range); image_invalid, image_too_many_pixels: a guide picture that is not "
        "a readable picture, or has too many pixels; setting_not_for_rig: a setting this rig "
        "does not have (the twin speed-up of hardware or of a rig host's twin); "
        "speedup_refused: a script's speed-up the rig does not allow (the message names what "
        "it allows); channel_not_on_rig: an input the rig does not have (a second heater on a "
        "one-heater rig; the message names what it has); pair_channel_unknown, pair_wrong_role: "
        "a run's input/output pair naming a channel the rig lacks, or an input that is no "
        "recorded actuator or an output that is no sensor; slot_ends_before_start, "
        "slot_too_long, slot_zone_missing: a booking's "
        "times (an end at or before the start, longer than a day unless said longer, a time "
        "without its zone); time_zone_unknown: a time zone that is not a known IANA name "
        "(a weekly series' zone)"
    )
    message: str | None = Field(
        default=None, description="the code's sentence in the reader's language"
    )
    errors: list[ProblemOut]


# -- sessions and users ----------------------------------------------------------------------


class CredentialsIn(_In):
    """Login: user name and password."""

    username: Annotated[str, Field(min_length=1, max_length=64)]
    password: Annotated[str, Field(min_length=1, max_length=1024)]


class SessionOut(_Out):
    """Who is logged in."""

    username: str
    display_name: str | None = Field(default=None, description="the name the user is shown by")
    role: Literal["student", "teacher"]
    expires_at: datetime | None
    must_change_password: bool = False
    admin: bool = Field(default=False, description="a lab administrator (accounts, rigs, LTI)")

    @classmethod
    def of(cls, who: Principal, display_name: str | None = None) -> SessionOut:
        """Build from a principal (and the display name, when known)."""
        return cls(
            username=who.username,
            display_name=display_name,
            role=who.role.value,
            expires_at=who.expires_at,
            must_change_password=who.must_change_password,
            admin=who.is_admin,
        )


class UserOut(_Out):
    """An account: its login name (normal form) and the name it is shown by."""

    username: str
    display_name: str | None
    role: Literal["student", "teacher"]
    created_at: datetime
    admin: bool = Field(default=False, description="a lab administrator (accounts, rigs, LTI)")

    @classmethod
    def of(cls, user: UserInfo) -> UserOut:
        """Build from a user record."""
        return cls(
            username=user.username,
            display_name=user.display_name,
            role=user.role.value,
            created_at=user.created_at,
            admin=user.admin,
        )


class NewUserIn(_In):
    """A new account (teachers only): the login name is normalised, the display name kept."""

    username: Annotated[str, Field(min_length=1, max_length=64)]
    display_name: Annotated[str | None, Field(max_length=256)] = None
    password: Annotated[str, Field(min_length=MIN_PASSWORD_LENGTH, max_length=MAX_PASSWORD_LENGTH)]
    role: Literal["student", "teacher"]
    admin: bool = Field(default=False, description="make this teacher a lab administrator")


class PasswordIn(_In):
    """A new password, with the acting user's current password (re-authentication)."""

    password: Annotated[str, Field(min_length=MIN_PASSWORD_LENGTH, max_length=MAX_PASSWORD_LENGTH)]
    current_password: Annotated[
        str | None,
        Field(
            max_length=MAX_PASSWORD_LENGTH,
            description="the password of the user making the change (required, also for "
            "a teacher changing someone else's)",
        ),
    ] = None


# -- rigs ---------------------------------------------------------------------------------------


class InputRangeOut(_Out):
    """What the rig's input accepts, and where it is."""

    min: float
    max: float
    unit: str
    safe: float
    last: float | None = Field(description="the controller's last input (null: the safe input)")
    live: bool = Field(description="true when inputs reach a device")


class ActuatorOut(_Out):
    """An actuator of the rig besides its input (a twin's disturbance fan)."""

    name: str
    unit: str
    min: float = Field(description="the lowest level it takes (PUT /api/rigs/{id}/channels/{name})")
    max: float = Field(description="the highest level it takes")
    default: float = Field(description="its declared default: every turn and run starts here")
    level: float | None = Field(description="its level now (null: not known to the lab)")
    recorded: bool = Field(
        description="every run records it (a kit's heater 2); false: only a closed-loop run "
        "does (a twin's fan, a disturbance for a controller)"
    )


class CooldownOut(_Out):
    """Cool-down between turns."""

    mode: Literal["none", "ambient"]
    tolerance: float
    max_seconds: float


class LimitsOut(_Out):
    """Time limits of the rig, in seconds."""

    control_time_limit: float
    idle_limit: float | None
    client_timeout: float
    power_off_grace: float
    cooldown: CooldownOut


class AccessOut(_Out):
    """The rig's access state as the caller sees it (Go-Lab Smart Device names)."""

    role: Literal["controller", "queued", "watcher"]
    queue_size: int
    queue_position: int | None
    estimated_time_until_control: float | None = Field(
        description="seconds; an upper bound assuming every turn ahead runs in full"
    )
    time_left: float | None = Field(
        description="seconds the controller has left (for everyone); null: nobody controls"
    )
    idle_time_left: float | None = Field(
        description="seconds until the idle limit ends the turn (the controller only)"
    )
    controller: str | None
    controller_name: str | None = Field(
        default=None, description="the controller's display name (null: none given)"
    )
    watchers: int = Field(
        description="users watching: live connections, and requests for this rig within "
        "the client timeout (listing the rigs does not count)"
    )
    can_extend: bool = Field(
        default=False,
        description="the controller may extend the turn now (POST .../control/more-time): "
        "nobody waits, its last minute, room left",
    )
    turn_ended: str | None = Field(
        default=None,
        description="answering a heartbeat (POST .../heartbeat) of a user who does not "
        "control the rig: how their last turn at it ended, in words (a teacher ended it, "
        "its time limit ran out...); null otherwise",
    )


class QueueSlotOut(_Out):
    """A queued user (teachers see the queue)."""

    username: str
    display_name: str | None = None
    position: int
    joined_at: datetime
    last_seen: datetime

    @classmethod
    def of(cls, slot: QueueSlot, names: Mapping[str, str] | None = None) -> QueueSlotOut:
        """Build from a queue slot (``names``: display names by login name)."""
        return cls(
            username=slot.username,
            display_name=(names or {}).get(slot.username),
            position=slot.position,
            joined_at=slot.joined_at,
            last_seen=slot.last_heartbeat_at,
        )


class WatcherOut(_Out):
    """A watching user (teachers see the list)."""

    username: str
    display_name: str | None = None
    connections: int
    last_seen: datetime

    @classmethod
    def of(cls, watcher: Watcher, names: Mapping[str, str] | None = None) -> WatcherOut:
        """Build from a watcher (``names``: display names by login name)."""
        return cls(
            username=watcher.username,
            display_name=(names or {}).get(watcher.username),
            connections=watcher.connections,
            last_seen=watcher.last_seen,
        )


class FurtherOutputOut(_Out):
    """An output of a rig besides ``y`` (a kit's sensor 2)."""

    name: str
    unit: str


class RigOut(_Out):
    """A rig: what it is, its state, limits, and access as the caller sees it."""

    id: str
    title: str
    kind: str
    state: Literal["off", "starting", "free", "in_use", "cooldown", "fault", "out_of_service"]
    in_service: bool
    fault: str | None
    input: InputRangeOut
    output_unit: str
    actuators: list[ActuatorOut] = Field(
        description="every actuator besides the input, with its level now and its declared "
        "default; a rig is handed over with each at its default"
    )
    outputs: list[FurtherOutputOut] = Field(
        default_factory=list,
        description="every output besides y (a kit's sensor 2, t2); a reading carries each",
    )
    speedup: float | None = Field(
        description="how many times faster than real time the rig runs: 1 for hardware; a "
        "twin the lab runs, its teacher setting twin_speedup or, during a turn that chose "
        "one (PUT /api/rigs/{id}/control/speedup), that turn's (the pace of the next run, and "
        "of the twin when no run is going: a run keeps the pace it started with); a twin on "
        "a rig host, its host's --speedup (null until the host has dialled in)"
    )
    limits: LimitsOut
    access: AccessOut
    queue: list[QueueSlotOut] | None = Field(description="teachers only")
    watcher_list: list[WatcherOut] | None = Field(description="teachers only")

    @classmethod
    def of(cls, view: RigView, names: Mapping[str, str] | None = None) -> RigOut:
        """Build from a rig view; ``names`` gives display names by login name (see
        :func:`people_named`)."""
        cfg, pub, acc = view.config, view.published, view.access
        names = names or {}
        declared = cfg.rig_spec.actuators
        return cls(
            id=view.id,
            title=view.title,
            kind=view.kind,
            state=view.state,
            in_service=view.in_service,
            fault=view.fault,
            input=InputRangeOut(
                min=pub.input_min,
                max=pub.input_max,
                unit=pub.input_unit,
                safe=pub.safe_input,
                last=view.last_input,
                live=pub.live,
            ),
            output_unit=pub.output_unit,
            actuators=[
                ActuatorOut(
                    name=a.name,
                    unit=a.unit,
                    min=declared[a.name].minimum,
                    max=declared[a.name].maximum,
                    default=a.default,
                    level=a.level,
                    recorded=declared[a.name].recorded,
                )
                for a in pub.actuators
            ],
            outputs=[
                FurtherOutputOut(name=o.name, unit=o.unit)
                for o in cfg.rig_spec.describe().further_outputs
            ],
            speedup=pub.speedup,
            limits=LimitsOut(
                control_time_limit=cfg.control_time_limit,
                idle_limit=cfg.idle_limit,
                client_timeout=view.client_timeout,
                power_off_grace=cfg.power_off_grace,
                cooldown=CooldownOut(
                    mode=cfg.cooldown.mode,
                    tolerance=cfg.cooldown.tolerance,
                    max_seconds=cfg.cooldown.max_seconds,
                ),
            ),
            access=AccessOut(
                role=acc.role,
                queue_size=acc.queue_size,
                queue_position=acc.queue_position,
                estimated_time_until_control=acc.estimated_time_until_control,
                time_left=acc.time_left,
                idle_time_left=acc.idle_time_left,
                controller=acc.controller,
                controller_name=None if acc.controller is None else names.get(acc.controller),
                watchers=acc.watchers,
                can_extend=acc.can_extend,
                turn_ended=acc.turn_ended,
            ),
            queue=None if view.queue is None else [QueueSlotOut.of(q, names) for q in view.queue],
            watcher_list=None
            if view.watcher_list is None
            else [WatcherOut.of(w, names) for w in view.watcher_list],
        )


def people_named(view: RigView) -> list[str]:
    """The login names a rig view names (controller, and for teachers the queue and watchers)."""
    named = [view.access.controller] if view.access.controller else []
    named += [q.username for q in view.queue or ()]
    named += [w.username for w in view.watcher_list or ()]
    return named


class InputIn(_In):
    """A new input for the rig, in its input unit (volts for the paper's box)."""

    u: Annotated[float, Field(allow_inf_nan=False, description="the new input value")]


class InputOut(_Out):
    """An accepted input command."""

    rig: str
    u: float
    applied: float | None = Field(description="the value the device applied; null if none")
    at: datetime
    run: int | None = Field(description="the run the input went to, if one is going")

    @classmethod
    def of(cls, result: InputResult) -> InputOut:
        """Build from an input result."""
        return cls(
            rig=result.rig_id, u=result.u, applied=result.applied, at=result.at, run=result.run_id
        )


class ExtendIn(_In):
    """Move the controller's time limit (negative cuts it)."""

    seconds: Annotated[float, Field(allow_inf_nan=False, ge=-86400, le=86400)]


class KickIn(_In):
    """Whom to kick: a user name, or nobody named for the controller."""

    username: Annotated[str | None, Field(max_length=64)] = None


class ServiceIn(_In):
    """Take a rig in or out of service."""

    in_service: bool


class ControlSessionOut(_Out):
    """One turn at a rig's controls, with how it ended."""

    id: int
    rig: str
    username: str
    started_at: datetime
    deadline: datetime
    ended_at: datetime | None
    end_reason: (
        Literal[
            "released",
            "time_limit",
            "idle",
            "client_gone",
            "kicked",
            "rig_fault",
            "server_restart",
            "booked",
        ]
        | None
    )
    ended_by: str | None

    @classmethod
    def of(cls, row: ControlSession) -> ControlSessionOut:
        """Build from a control session row."""
        return cls.model_validate(
            {
                "id": row.id,
                "rig": row.rig_id,
                "username": row.username,
                "started_at": row.started_at,
                "deadline": row.deadline,
                "ended_at": row.ended_at,
                "end_reason": row.end_reason,
                "ended_by": row.ended_by,
            }
        )
