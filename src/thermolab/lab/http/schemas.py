"""JSON bodies of the lab's HTTP API (pydantic models, camelCase on the wire).

Request bodies refuse unknown fields and values of the wrong type, so a typo
is a 422 naming the field rather than a silently ignored setting.
"""

from __future__ import annotations

import math
from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PlainValidator,
    WithJsonSchema,
)
from pydantic.alias_generators import to_camel
from pydantic_core import PydanticCustomError

from thermolab.ident.registry import METHOD_NAMES
from thermolab.lab.access import QueueSlot, RigView
from thermolab.lab.db.models import ControlSession
from thermolab.lab.presence import Watcher
from thermolab.lab.runs import MAX_DT, MAX_SAMPLES, MIN_DT, OFFSET_MODES, RunRecord, RunRequest
from thermolab.lab.runs.request import RUN_SETTINGS
from thermolab.lab.service import InputResult
from thermolab.lab.users import Principal, UserInfo

__all__ = [
    "AccessOut",
    "ControlSessionOut",
    "CooldownOut",
    "CredentialsIn",
    "ErrorOut",
    "ExtendIn",
    "InputIn",
    "InputOut",
    "InputRangeOut",
    "KickIn",
    "LimitsOut",
    "NewUserIn",
    "OperatingPointOut",
    "PasswordIn",
    "QueueSlotOut",
    "RigOut",
    "RunIn",
    "RunOut",
    "ServiceIn",
    "SessionOut",
    "UserOut",
    "ValidationErrorOut",
    "WatcherOut",
]


class _In(BaseModel):
    model_config = ConfigDict(
        alias_generator=to_camel, populate_by_name=True, extra="forbid", strict=True
    )


class _Out(BaseModel):
    model_config = ConfigDict(alias_generator=to_camel, populate_by_name=True)


# -- errors --------------------------------------------------------------------------------


class ErrorOut(_Out):
    """Every 4xx answer: ``detail`` says what was wrong and what is allowed; ``code`` is stable."""

    detail: str
    code: str


class ValidationErrorOut(_Out):
    """A 422 for a malformed body: ``detail`` in words, ``errors`` one per problem."""

    detail: str
    errors: list[dict[str, Any]]


# -- sessions and users ----------------------------------------------------------------------


class CredentialsIn(_In):
    """Login: user name and password."""

    username: Annotated[str, Field(min_length=1, max_length=64)]
    password: Annotated[str, Field(min_length=1, max_length=1024)]


class SessionOut(_Out):
    """Who is logged in."""

    username: str
    role: Literal["student", "teacher"]
    expires_at: datetime | None

    @classmethod
    def of(cls, who: Principal) -> SessionOut:
        """Build from a principal."""
        return cls(username=who.username, role=who.role.value, expires_at=who.expires_at)


class UserOut(_Out):
    """An account."""

    username: str
    role: Literal["student", "teacher"]
    created_at: datetime

    @classmethod
    def of(cls, user: UserInfo) -> UserOut:
        """Build from a user record."""
        return cls(username=user.username, role=user.role.value, created_at=user.created_at)


class NewUserIn(_In):
    """A new account (teachers only)."""

    username: Annotated[str, Field(min_length=1, max_length=64)]
    password: Annotated[str, Field(min_length=8, max_length=1024)]
    role: Literal["student", "teacher"]


class PasswordIn(_In):
    """A new password; users changing their own also give the current one."""

    password: Annotated[str, Field(min_length=8, max_length=1024)]
    current_password: Annotated[str | None, Field(max_length=1024)] = None


# -- rigs ---------------------------------------------------------------------------------------


class InputRangeOut(_Out):
    """What the rig's input accepts, and where it is."""

    min: float
    max: float
    unit: str
    safe: float
    last: float | None = Field(description="the controller's last input (null: the safe input)")
    live: bool = Field(description="true when inputs reach a device")


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
    watchers: int = Field(
        description="users watching: live connections, and requests for this rig within "
        "the client timeout (listing the rigs does not count)"
    )


class QueueSlotOut(_Out):
    """A queued user (teachers see the queue)."""

    username: str
    position: int
    joined_at: datetime
    last_seen: datetime

    @classmethod
    def of(cls, slot: QueueSlot) -> QueueSlotOut:
        """Build from a queue slot."""
        return cls(
            username=slot.username,
            position=slot.position,
            joined_at=slot.joined_at,
            last_seen=slot.last_heartbeat_at,
        )


class WatcherOut(_Out):
    """A watching user (teachers see the list)."""

    username: str
    connections: int
    last_seen: datetime

    @classmethod
    def of(cls, watcher: Watcher) -> WatcherOut:
        """Build from a watcher."""
        return cls(
            username=watcher.username,
            connections=watcher.connections,
            last_seen=watcher.last_seen,
        )


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
    limits: LimitsOut
    access: AccessOut
    queue: list[QueueSlotOut] | None = Field(description="teachers only")
    watcher_list: list[WatcherOut] | None = Field(description="teachers only")

    @classmethod
    def of(cls, view: RigView) -> RigOut:
        """Build from a rig view."""
        cfg, pub, acc = view.config, view.published, view.access
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
                watchers=acc.watchers,
            ),
            queue=None if view.queue is None else [QueueSlotOut.of(q) for q in view.queue],
            watcher_list=None
            if view.watcher_list is None
            else [WatcherOut.of(w) for w in view.watcher_list],
        )


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


FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]


def _offset(value: object) -> str | float:
    # One message for the one choice (a union type would report each branch's error).
    if isinstance(value, str) and value in OFFSET_MODES:
        return value
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    raise PydanticCustomError(
        "offset",
        "Input should be {modes} or a finite number (a known ambient)",
        {"modes": ", ".join(repr(m) for m in OFFSET_MODES)},
    )


def _method_name(value: str) -> str:
    if value not in METHOD_NAMES:
        raise PydanticCustomError(
            "method", "Input should be one of {names}", {"names": ", ".join(METHOD_NAMES)}
        )
    return value


def _setting(name: str) -> Any:
    """The field of run setting ``name``: its range, unit and help from the registry.

    The range is :data:`thermolab.lab.runs.request.RUN_SETTINGS`' (the registry's,
    narrowed where the lab says why); ``null`` stands for the registry's default.
    """
    setting = RUN_SETTINGS[name]
    ranged = setting.type in ("integer", "number")
    low = setting.minimum if ranged else None
    high = setting.maximum if ranged else None
    unit = f" ({setting.unit})" if setting.unit else ""
    default = setting.default
    shown = list(default) if isinstance(default, tuple) else default
    return Field(
        gt=low if setting.exclusive_minimum else None,
        ge=None if setting.exclusive_minimum else low,
        lt=high if setting.exclusive_maximum else None,
        le=None if setting.exclusive_maximum else high,
        allow_inf_nan=False if setting.type == "number" else None,
        description=f"{setting.help}{unit}; null: the registry's default {shown!r}",
    )


#: The method names, checked and published from the registry.
MethodName = Annotated[
    str, AfterValidator(_method_name), WithJsonSchema({"enum": list(METHOD_NAMES)})
]


class RunIn(_In):
    """START: the run's schedule, input and identification methods (the paper's panels).

    The method settings (``window``...``w0``) are the registry's
    (:mod:`thermolab.ident.registry`, published at ``GET /api/methods``) as the
    lab narrows them in :data:`thermolab.lab.runs.request.RUN_SETTINGS`.
    """

    dt: Annotated[
        float,
        # Published here, checked once by thermolab.lab.runs.request.check_request.
        Field(
            allow_inf_nan=False,
            json_schema_extra={"minimum": MIN_DT, "maximum": MAX_DT},
            description="sample period, s",
        ),
    ]
    samples: Annotated[int, Field(ge=1, le=MAX_SAMPLES, description="samples to take")]
    signal: Annotated[
        str | None,
        Field(
            max_length=200,
            description="input signal: const:U, step:U0:U1@T, square:LOW:HIGH:HZ, "
            "sine:OFFSET:AMP:HZ, prbs:LOW:HIGH:BIT_S[:SEED]; null for a manual set point",
        ),
    ] = None
    setpoint: Annotated[
        float | None,
        Field(allow_inf_nan=False, description="manual input at START (with no signal)"),
    ] = None
    methods: Annotated[
        list[MethodName],
        Field(min_length=1, max_length=len(METHOD_NAMES), description="identification methods"),
    ] = ["srm", "lsm"]
    window: Annotated[int | None, _setting("window")] = None
    block: Annotated[int | None, _setting("block")] = None
    gamma: Annotated[float | None, _setting("gamma")] = None
    pmax: Annotated[float | None, _setting("pmax")] = None
    # [a0, b0] of the first-order model, or [a0, b0, c0] with offset "fit".
    w0: Annotated[list[FiniteFloat] | None, _setting("w0"), Field(min_length=2, max_length=3)] = (
        None
    )
    offset: Annotated[
        str | float,
        PlainValidator(_offset),
        WithJsonSchema(
            {"anyOf": [{"type": "string", "enum": list(OFFSET_MODES)}, {"type": "number"}]}
        ),
        Field(
            description="the operating point: 'initial' removes the first sample (an "
            "equilibrium at 0 V), 'fit' estimates a constant term, 'none' is the raw "
            "regression, a number is the known ambient output; 'auto' is 'initial' on a rig "
            "at rest and 'fit' on a warm one (the run's operatingPoint says which and why)"
        ),
    ] = "auto"

    def request(self) -> RunRequest:
        """The run service's request."""
        settings = {name: getattr(self, name) for name in RUN_SETTINGS}
        if settings["w0"] is not None:
            settings["w0"] = tuple(settings["w0"])
        return RunRequest(
            dt=self.dt,
            samples=self.samples,
            signal=self.signal,
            setpoint=self.setpoint,
            methods=tuple(self.methods),
            offset=self.offset,
            **settings,
        )


class OperatingPointOut(_Out):
    """How a run's identifiers treat the operating point, and why."""

    asked: str | float = Field(description="the request's offset")
    used: str | float | None = Field(
        description="the mode used; null when no chosen method regresses on the output"
    )
    at_rest: bool | None = Field(description="whether the lab judged the rig at rest at START")
    reason: str


class RunOut(_Out):
    """A run: what was asked, how far it got, how it ended, each method's latest estimate."""

    id: int
    rig: str
    username: str
    status: Literal["running", "finished", "stopped", "interrupted", "failed"]
    dt: float
    samples: int | None
    samples_stored: int
    samples_taken: int
    signal: str | None
    setpoint: float | None
    methods: list[str]
    settings: dict[str, Any]
    started_at: datetime
    ended_at: datetime | None
    end_reason: str | None
    results: dict[str, Any] = Field(
        description="per method: latest estimate (K, tau, W, valid, final, extras.reason...), "
        "error, and once the run is over stats: mean/max/min of K and tau over the last "
        "2000 samples and converged_at, the samples to converge within ±1 % "
        "(thermolab.ident.Trajectory.stats / converged_at)"
    )
    operating_point: OperatingPointOut | None = Field(
        description="how the operating point was handled (null for runs from before it was kept)"
    )

    @classmethod
    def of(cls, run: RunRecord) -> RunOut:
        """Build from a run record."""
        return cls.model_validate(
            {
                "id": run.id,
                "rig": run.rig_id,
                "username": run.username,
                "status": run.status,
                "dt": run.dt,
                "samples": run.samples,
                "samples_stored": run.samples_stored,
                "samples_taken": run.samples_taken,
                "signal": run.signal,
                "setpoint": run.setpoint,
                "methods": run.methods,
                "settings": run.settings,
                "started_at": run.started_at,
                "ended_at": run.ended_at,
                "end_reason": run.end_reason,
                "results": run.results,
                "operating_point": run.operating_point,
            }
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
