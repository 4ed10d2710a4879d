"""The runs' routes and their bodies: START and END on a rig, listings, one run, its exports.

START's body (:class:`RunIn`) is built from the method registry as the lab
carries it (:data:`thermolab.lab.runs.request.RUN_SETTINGS`): method names,
each setting's range, unit and help; ``null`` is the registry's default
(``tests/ident/test_registry.py`` checks it against the registry). A run is
answered as :class:`RunOut` (the control routes and the live stream send it too).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import APIRouter, status
from fastapi.responses import JSONResponse, StreamingResponse
from pydantic import AfterValidator, Field, PlainValidator, WithJsonSchema
from pydantic_core import PydanticCustomError

from thermolab.ident.registry import METHOD_NAMES
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.control_schemas import ControlIn
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    LabDep,
    RigId,
    RigQuery,
    RunId,
    SheetDep,
    UserDep,
    UserQuery,
    documented_errors,
)
from thermolab.lab.runs import (
    MAX_DT,
    MAX_SAMPLES,
    MIN_DT,
    OFFSET_MODES,
    RunRecord,
    RunRequest,
    samples_csv,
)
from thermolab.lab.runs.request import RUN_SETTINGS
from thermolab.records import ChannelRole

__all__ = ["ChannelOut", "MethodName", "OperatingPointOut", "RunIn", "RunOut", "router"]


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


class RunIn(In):
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
    ] = ["srm", "lsm"]  # noqa: RUF012 (pydantic copies a mutable default per instance)
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
            "regression, a number is the known ambient output; 'auto' is decided from the data "
            "(the run's operatingPoint and each result say what was used and found)"
        ),
    ] = "auto"
    control: ControlIn | None = Field(
        default=None,
        description="a PID on the output (a closed-loop run): mode, set point, gains, "
        "adaptive; null: open loop (GET /api/control publishes every range)",
    )
    input: Annotated[
        str,
        Field(
            min_length=1,
            max_length=40,
            description="the input of the pair identified: 'u' (the rig's input, the default) "
            "or a further input the rig declares and records (a kit's 'q2'); the signal or "
            "the manual input drives it and u rests. Open loop only",
        ),
    ] = "u"
    output: Annotated[
        str,
        Field(
            min_length=1,
            max_length=40,
            description="the output of the pair identified: 'y' (the default) or a further "
            "output the rig declares (a kit's 't2'); 422 pair_channel_unknown for a name the "
            "rig lacks, pair_wrong_role for an input or output in the wrong place",
        ),
    ] = "y"

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
            control=None if self.control is None else self.control.request(),
            input=self.input,
            output=self.output,
            **settings,
        )


class OperatingPointOut(Out):
    """How a run's identifiers treat the operating point, and why."""

    asked: str | float = Field(description="the request's offset")
    used: str | float | None = Field(
        description="the mode used; null when no chosen method regresses on the output"
    )
    reason: str


class ChannelOut(Out):
    """One channel of a run's samples (:class:`thermolab.records.ChannelSpec`)."""

    name: str = Field(description="the column's name in the CSV and the sample's channels")
    unit: str = Field(description="its unit ('' for a count or a flag)")
    role: ChannelRole
    description: str


class RunOut(Out):
    """A run: what was asked, how far it got, how it ended, each method's latest estimate."""

    id: int
    rig: str
    username: str
    display_name: str | None = Field(default=None, description="the owner's display name")
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
        "error, and once the run is over stats: mean/max/min of K and tau after "
        "convergence within ±1 % (over: after_convergence; last: how many samples) or, "
        "where the estimates never converge, over the last 2000 samples (over: last), "
        "and converged_at, the samples to converge: thermolab identify's figures of the "
        "same record (thermolab.ident.table_figures)"
    )
    operating_point: OperatingPointOut | None = Field(
        description="how the operating point was handled (null for runs from before it was kept)"
    )
    ends_at: datetime | None = Field(
        default=None,
        description="the run's planned end: START plus samples × dt in real time (null for "
        "runs from before it was kept)",
    )
    timing: dict[str, Any] | None = Field(
        default=None,
        description="once the run is over: rig ('real' or 'twin'), maxLateness and "
        "p95Lateness (wall-clock, s; null for a twin, whose data are exact), periodSpread (std "
        "of the periods between the readings' times over their median) and warnings",
    )
    channels: list[ChannelOut] = Field(
        default_factory=list,
        description="every channel of the run's samples in record order (t, u, y, k, t_read, "
        "jitter, lateness, then what the rig or controller publishes), with its unit and role; "
        "empty for runs from before they were kept",
    )

    control: dict[str, Any] | None = Field(
        default=None,
        description="a closed-loop run's controller (mode, setpoint, gains, pid, adaptive with "
        "retunes and last_reason), live while it runs; null for an open loop",
    )

    @classmethod
    def of(cls, run: RunRecord, names: Mapping[str, str] | None = None) -> RunOut:
        """Build from a run record (every field by the record's name; ``rig`` is its ``rig_id``;
        ``names``: display names by login name, for ``display_name``)."""
        own = {"rig", "display_name"}
        fields = {name: getattr(run, name) for name in cls.model_fields if name not in own}
        shown = (names or {}).get(run.username)
        return cls.model_validate({**fields, "rig": run.rig_id, "display_name": shown})


router = APIRouter(**AUTHENTICATED)


@router.post(
    "/rigs/{rig_id}/runs",
    response_model=RunOut,
    status_code=status.HTTP_201_CREATED,
    tags=["runs"],
    summary="START a run",
    responses=documented_errors(403, 404, 409, 422),
)
def start_run(rig_id: RigId, body: RunIn, who: UserDep, lab: LabDep) -> RunOut:
    """Start sampling the rig you control, with a signal or a manual set point and the
    identification methods to run live (change the set point with PUT .../input).
    """
    lab.config.rig(rig_id)  # an unknown rig is a 404 that names the lab's rigs
    return RunOut.of(lab.rig_runs.start(rig_id, who, body.request()))


@router.post(
    "/rigs/{rig_id}/runs/current/stop",
    response_model=RunOut,
    tags=["runs"],
    summary="END the current run",
    responses=documented_errors(403, 404, 409),
)
def stop_run(rig_id: RigId, who: UserDep, lab: LabDep) -> RunOut:
    """END: stop after the current sample and compute the final estimates (controller or
    teacher). Returns at once; the run's status changes when it has ended.
    """
    lab.config.rig(rig_id)
    return RunOut.of(lab.rig_runs.stop(rig_id, who))


@router.get(
    "/runs",
    response_model=list[RunOut],
    tags=["runs"],
    summary="Runs",
    responses=documented_errors(403, 404, 422),
)
def list_runs(
    who: UserDep,
    lab: LabDep,
    rig: RigQuery = None,
    user: UserQuery = None,
) -> list[RunOut]:
    """Runs, newest first: your own, or everyone's for a teacher (``user`` narrows it to one
    user; a student naming someone else gets 403, a teacher naming nobody known 404).
    """
    runs = lab.runs.list(who, rig, user=user)
    names = lab.names.names({run.username for run in runs})
    return [RunOut.of(run, names) for run in runs]


@router.get(
    "/runs/{run_id}",
    response_model=RunOut,
    tags=["runs"],
    summary="One run",
    responses=documented_errors(403, 404),
)
def get_run(run_id: RunId, who: UserDep, lab: LabDep) -> RunOut:
    """A run with each method's latest (or final) estimate."""
    run = lab.runs.get(run_id, who)
    return RunOut.of(run, lab.names.names([run.username]))


@router.get(
    "/runs/{run_id}/samples.csv",
    tags=["runs"],
    summary="The run's samples as CSV",
    response_class=StreamingResponse,
    responses={200: {"content": {"text/csv": {}}}, **documented_errors(403, 404)},
)
def run_samples_csv(run_id: RunId, who: UserDep, lab: LabDep, sheet: SheetDep) -> StreamingResponse:
    """Columns ``t,u,y`` first, then every other channel of the run by name (``k``,
    ``t_read``, ``jitter``, ``lateness``, and any a rig adds): the file feeds straight
    into ``thermolab identify`` (format: :mod:`thermolab.records`).

    ``?dialect=pt-BR`` (or ``en``, ``es``): the spreadsheet form (``;`` and a decimal
    comma in pt-BR and es, units in the headings), which ``thermolab identify`` reads too.
    """
    channels, rows = lab.runs.record_rows(run_id, who)
    return StreamingResponse(
        samples_csv(channels, rows, sheet),
        media_type="text/csv" if sheet is None else "text/csv; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="run-{run_id}.csv"'},
    )


@router.get(
    "/runs/{run_id}/export.json",
    tags=["runs"],
    summary="The run, its samples and every method's results as JSON",
    responses=documented_errors(403, 404),
)
def run_export(run_id: RunId, who: UserDep, lab: LabDep) -> JSONResponse:
    """Everything stored about a run: settings, samples, trajectories, final estimates."""
    exported = lab.runs.export(run_id, who)
    exported["run"] = RunOut.of(exported["run"]).model_dump(mode="json", by_alias=True)
    return JSONResponse(
        exported,
        headers={"Content-Disposition": f'attachment; filename="run-{run_id}.json"'},
    )
