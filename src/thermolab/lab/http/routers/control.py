"""Routes of the closed loop: the declared parameters, a rig's loop, live commands, the table.

Live commands act on the rig's current run (started with ``control`` in its
START body) from its next sample on; only the controller, in the turn the run
belongs to, may send them (the access checks of ``PUT .../input``), and the
interlocks and the safe state still come first in the sampling loop (a rig
host's run: checked here the same way, applied by the host's runner).
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query

from thermolab.control import PARAMETERS, control_json, step_setpoint
from thermolab.errors import SetpointNoStepError, SetpointRangeError
from thermolab.lab.http.control_schemas import FanIn, GainsIn, LoopOut, ModeIn, SetpointIn
from thermolab.lab.http.deps import AUTHENTICATED, LabDep, RigId, RunId, UserDep, documented_errors
from thermolab.lab.http.routers.runs import RunOut
from thermolab.lab.runs.control import PRIMARY_PAIR
from thermolab.lab.runs.model_pair import check_loop_model, model_pair, output_limit
from thermolab.lab.runs.tuning_table import closed_loop_figures, run_model, tuning_table
from thermolab.lab.service import Lab
from thermolab.runner import LoopCommands

__all__ = ["router"]

#: The tuning table's closed-loop speed, as the control layer declares it.
TAU_C = PARAMETERS["tau_c"]
#: A bound on any set point the schema takes (the rig's own output range is checked
#: by the lab); it keeps the query within numbers a model can simulate.
SETPOINT_BOUND = 1e4

router = APIRouter(**AUTHENTICATED)


@router.get("/control", tags=["control"], summary="The closed loop's parameters and rules")
def control_parameters() -> dict[str, Any]:
    """Every PID and tuning parameter as :data:`thermolab.control.PARAMETERS` declares it
    (type, default, range, unit, help), the tuning rules with their forms and whether they
    take a closed-loop speed, and the modes. The browser's "Closed loop" panel is built
    from it.
    """
    return control_json()


@router.get(
    "/rigs/{rig_id}/loop",
    response_model=LoopOut,
    tags=["control"],
    summary="A rig's closed-loop facts and its run's loop",
    responses=documented_errors(404),
)
def rig_loop(rig_id: RigId, who: UserDep, lab: LabDep) -> LoopOut:
    """Units, ranges, the output limit (a set point must stay below it), the disturbance
    fan if the rig has one, the heater and sensor pairs a loop may control (a kit's
    two), and the current run's control loop (mode, set point, gains,
    adaptive state and why it holds the gains).
    """
    cfg = lab.config.rig(rig_id)
    published = lab.hub.published(rig_id)
    spec = cfg.rig_spec
    info = spec.describe()
    lab.presence.touch(rig_id, who.username)
    return LoopOut(
        rig=rig_id,
        output_unit=published.output_unit,
        input_unit=published.input_unit,
        input_range=[published.input_min, published.input_max],
        safe_input=published.safe_input,
        output_limit=info.output_limit,
        closed_loop=bool(published.output_unit),
        fan=None if spec.fan is None else spec.fan.to_dict(),
        pairs=[
            {
                "heater": heater,
                "sensor": sensor,
                "inputUnit": published.input_unit if own else info.inputs[heater].unit,
                "inputRange": [published.input_min, published.input_max]
                if own
                else list(info.inputs[heater].range),
                "outputUnit": published.output_unit if own else info.outputs[sensor].unit,
                "outputLimit": info.output_limit if own else info.outputs[sensor].limit,
            }
            for heater, sensor in info.loop_pairs
            for own in (heater == PRIMARY_PAIR[0],)
        ],
        loop=lab.rig_runs.loop_state(rig_id),
    )


def _check_step(target: float, y0: float, output_limit: float | None, unit: str) -> None:
    """A tuning step's set point: below the rig's output limit, and away from ``y0``."""
    if output_limit is not None and target >= output_limit:
        raise SetpointRangeError(
            f"set point {target:g} {unit} is not below the rig's output limit "
            f"{output_limit:g} {unit}"
        )
    if abs(target - y0) <= 1e-9 * max(1.0, abs(y0)):
        raise SetpointNoStepError(
            f"set point {target:g} {unit} is the output the step starts from ({y0:g} {unit}): "
            "no step to tune for; choose a set point away from it"
        )


def _command(
    lab: Lab, rig_id: str, who: Any, kind: str, payload: dict[str, Any], act: Any
) -> RunOut:
    lab.config.rig(rig_id)
    return RunOut.of(lab.rig_runs.command(rig_id, who, kind, payload, act))


_COMMAND_ERRORS = documented_errors(403, 404, 409, 422)


@router.put(
    "/rigs/{rig_id}/runs/current/mode",
    response_model=RunOut,
    tags=["control"],
    summary="Switch the run's controller between manual and auto",
    responses=_COMMAND_ERRORS,
)
def set_mode(rig_id: RigId, body: ModeIn, who: UserDep, lab: LabDep) -> RunOut:
    """``auto``: the PID takes over bumplessly from the input in force (a ``setpoint`` given
    with it is then a step); ``manual``: the PID's last output is held (or ``u``) and the
    PID tracks it. 409 ``no_run`` without a run, ``not_closed_loop`` for an open-loop run.
    """

    def act(experiment: LoopCommands) -> None:
        if body.mode == "auto":
            experiment.set_auto(body.setpoint)
        else:
            experiment.set_manual(body.u)

    payload = body.model_dump(exclude_none=True)
    return _command(lab, rig_id, who, "mode", payload, act)


@router.put(
    "/rigs/{rig_id}/runs/current/setpoint",
    response_model=RunOut,
    tags=["control"],
    summary="Change the set point",
    responses=_COMMAND_ERRORS,
)
def set_setpoint(rig_id: RigId, body: SetpointIn, who: UserDep, lab: LabDep) -> RunOut:
    """A new set point in the output unit, below the rig's output limit (422
    ``setpoint_out_of_range`` otherwise)."""
    return _command(
        lab, rig_id, who, "setpoint", {"setpoint": body.setpoint},
        lambda experiment: experiment.set_setpoint(body.setpoint),
    )  # fmt: skip


@router.put(
    "/rigs/{rig_id}/runs/current/gains",
    response_model=RunOut,
    tags=["control"],
    summary="Change the PID's gains (bumpless)",
    responses=_COMMAND_ERRORS,
)
def set_gains(rig_id: RigId, body: GainsIn, who: UserDep, lab: LabDep) -> RunOut:
    """New gains, each finite and inside its published range (422 ``gain_out_of_range``)."""
    from thermolab.control import PIDGains

    gains = PIDGains(body.kp, body.ti, body.td)  # checked before anything is recorded
    return _command(
        lab, rig_id, who, "gains", gains.to_dict(), lambda experiment: experiment.set_gains(gains)
    )


@router.put(
    "/rigs/{rig_id}/runs/current/fan",
    response_model=RunOut,
    tags=["control"],
    summary="Run the disturbance fan",
    responses=_COMMAND_ERRORS,
)
def set_fan(rig_id: RigId, body: FanIn, who: UserDep, lab: LabDep) -> RunOut:
    """The disturbance fan at ``percent`` of full speed, from the run's next sample on
    (422 for a rig without a fan, or outside 0-100 %)."""
    return _command(
        lab, rig_id, who, "fan", {"percent": body.percent},
        lambda experiment: experiment.set_fan(body.percent),
    )  # fmt: skip


@router.get(
    "/runs/{run_id}/tuning",
    tags=["control"],
    summary="The tuning table of a run's identified model",
    responses=documented_errors(403, 404, 422),
)
def run_tuning(
    run_id: RunId,
    who: UserDep,
    lab: LabDep,
    setpoint: Annotated[
        float | None,
        Query(
            ge=-SETPOINT_BOUND,
            le=SETPOINT_BOUND,
            description="the step's set point, in the output unit (default: the output a "
            "step of the input from rest halfway to the far end of its range settles at, "
            "below the output limit)",
        ),
    ] = None,
    tau_c: Annotated[
        float | None,
        Query(
            alias="tauC",
            gt=TAU_C.minimum,
            le=TAU_C.maximum,
            description="closed-loop speed of imc and simc, s (default: theta)",
        ),
    ] = None,
    method: Annotated[
        str | None,
        Query(min_length=1, max_length=16, pattern="^[a-z]+$", description="the model's method"),
    ] = None,
    heater: Annotated[
        str | None,
        Query(
            min_length=1,
            max_length=32,
            pattern="^[a-z0-9_]+$",
            description="the heater of the loop to tune (default u, or the sensor's pair's)",
        ),
    ] = None,
    sensor: Annotated[
        str | None,
        Query(
            min_length=1,
            max_length=32,
            pattern="^[a-z0-9_]+$",
            description="the sensor of the loop to tune (default y, or the heater's pair's)",
        ),
    ] = None,
) -> dict[str, Any]:
    """From the run's identified FOPDT model (Ks, Ts, θ): each rule's Kp, Ti, Td, the
    predicted closed-loop step from the run's starting point and its overshoot, 2 %
    settling time and IAE. For a closed-loop run, ``closedLoop`` has its measured figures
    beside the prediction of the model its gains came from.

    The table says which pair its model is of (``pair``: the run's ``input`` and
    ``output``, ``u``/``y`` for a run from before pairs). Given the loop's
    ``heater`` and ``sensor``, a model of another pair is refused (422
    ``model_pair_mismatch``): a kit's Q2 -> T2 model never tunes the Q1/T1 loop.
    """
    TAU_C.check(tau_c)
    record = lab.runs.get(run_id, who)
    info = lab.config.rig(record.rig_id).rig_spec.describe()
    if heater is not None or sensor is not None:
        # One named: the other is its loop pair's (a kit's q2 goes with t2).
        paired = dict(info.loop_pairs) if heater is not None else {}
        by_sensor = {s: h for h, s in info.loop_pairs}
        heater = heater or by_sensor.get(sensor or "", PRIMARY_PAIR[0])
        sensor = sensor or paired.get(heater, PRIMARY_PAIR[1])
        check_loop_model(info, record.settings, heater, sensor, run_id)
    exported = lab.runs.export(run_id, who)
    samples = exported.get("samples") or {}
    published = lab.hub.published(record.rig_id)
    # The model's pair: its input's range and rest, its output's first sample and limit.
    pair = model_pair(record.settings)
    limits = pair.limits(info, (published.input_min, published.input_max))
    out: dict[str, Any] = {"run": run_id, "table": None, "closedLoop": None, "note": None}
    ys, us = samples.get(pair.output) or [], samples.get("u") or []
    y0 = float(ys[0]) if ys else 0.0
    u0 = pair.rest(info) if pair.drives_further else published.safe_input
    unit = published.output_unit if pair.standard else pair.units(info)[1]
    try:
        name, model, trusted = run_model(record.results, method)
        limit = output_limit(info, pair)
        target = setpoint
        if target is None:
            # From the rig's declared ranges: a step of the input from rest, never
            # the middle of a range centred on rest (the ±10 V box: no step at all).
            target = step_setpoint(model, y0=y0, u_rest=u0, u_limits=limits, output_limit=limit)
        _check_step(target, y0, limit, unit)
        table = tuning_table(
            model, dt=record.dt, y0=y0, u0=u0, setpoint=target, u_limits=limits, tau_c=tau_c
        )
    except ValueError as exc:
        # A closed-loop run's measured figures come with or without a table of its own.
        if method is not None or setpoint is not None or record.control is None:
            raise
        out["note"] = str(exc)
    else:
        out["table"] = {**table, "method": name, "trusted": trusted, "pair": pair.to_dict()}
    control = (record.settings or {}).get("control")
    if control is not None and us:
        limits, rest = (published.input_min, published.input_max), published.safe_input
        actuator = lab.config.rig(record.rig_id).rig_spec.actuators.get(control.get("heater") or "")
        if actuator is not None:  # a loop on a further pair: that heater's range and rest
            limits, rest = actuator.range, actuator.default
        out["closedLoop"] = closed_loop_figures(samples, record.dt, control, limits, rest)
    return out
