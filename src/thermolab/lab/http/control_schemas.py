"""JSON bodies of the closed loop: a run's controller at START, the live commands, the table.

Every range is published from the control layer's one declaration
(:data:`thermolab.control.PARAMETERS`) and checked once, by it
(:func:`thermolab.lab.runs.control.build_control_loop`, ``PIDGains``): a value
out of range is 422 ``gain_out_of_range`` with the reason, not a schema
error, so the page, the API and the command line say the same thing.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field

from thermolab.control import PARAMETERS
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.runs.control import PRIMARY_PAIR, ControlRequest

__all__ = ["ControlIn", "FanIn", "GainsIn", "LoopOut", "ModeIn", "SetpointIn"]

#: A channel's name (thermolab.records.ChannelSpec), as the rig declares it.
_CHANNEL = r"^[a-z][a-z0-9_]*$"


def _declared(name: str) -> Any:
    """A field published with its declared range, unit and help (checked by the control layer)."""
    p = PARAMETERS[name]
    extra: dict[str, Any] = {}
    if p.minimum is not None:
        extra["minimum"] = -p.maximum if p.magnitude and p.maximum is not None else p.minimum
    if p.maximum is not None:
        extra["maximum"] = p.maximum
    if p.choices:
        extra["enum"] = list(p.choices)
    unit = f" ({p.unit})" if p.unit else ""
    return Field(json_schema_extra=extra, description=f"{p.help}{unit}; allowed: {p.allowed()}")


class GainsIn(In):
    """PID gains (parallel form); ``td`` 0 is a PI."""

    kp: Annotated[float, _declared("kp")]
    ti: Annotated[float, _declared("ti")]
    td: Annotated[float, _declared("td")] = 0.0


class ControlIn(GainsIn):
    """A closed-loop run's controller: mode, set point, gains, adaptive retuning."""

    mode: Literal["manual", "auto"] = "auto"
    setpoint: float = Field(description="set point of the output, in the rig's output unit")
    adaptive: bool = Field(default=False, description="retune live from WLSM (off by default)")
    rule: Annotated[str | None, _declared("rule")] = None
    form: Annotated[str | None, _declared("form")] = None
    tau_c: Annotated[float | None, _declared("tau_c")] = None
    every: Annotated[int | None, _declared("every")] = None
    max_change: Annotated[float | None, _declared("max_change")] = None
    settle_tol: Annotated[float | None, _declared("settle_tol")] = None
    excitation: Annotated[float | None, _declared("excitation")] = None
    kp_range: Annotated[list[float] | None, _declared("kp_range")] = None
    ti_range: Annotated[list[float] | None, _declared("ti_range")] = None
    derivative_filter: Annotated[float | None, _declared("derivative_filter")] = None
    model: list[float] | None = Field(
        default=None,
        description="[K, tau, theta]: the model the gains came from (its prediction is shown "
        "beside the measured run)",
    )
    heater: str = Field(
        default=PRIMARY_PAIR[0],
        min_length=1,
        max_length=40,
        pattern=_CHANNEL,
        description="the input the PID drives, by the rig's name: u (default, the run's "
        "input) or a further input that has a sensor (a kit's q2); the other heater stays "
        "settable by hand, a disturbance (422 loop_pair_not_on_rig for a pair the rig lacks)",
    )
    sensor: str = Field(
        default=PRIMARY_PAIR[1],
        min_length=1,
        max_length=40,
        pattern=_CHANNEL,
        description="the output the PID controls, paired with heater: y (default) or a "
        "further output (a kit's t2)",
    )

    def request(self) -> ControlRequest:
        """The run service's request."""
        return ControlRequest(
            setpoint=self.setpoint,
            kp=self.kp,
            ti=self.ti,
            td=self.td,
            mode=self.mode,
            adaptive=self.adaptive,
            rule=self.rule,
            form=self.form,
            tau_c=self.tau_c,
            every=self.every,
            max_change=self.max_change,
            settle_tol=self.settle_tol,
            excitation=self.excitation,
            kp_range=None if self.kp_range is None else tuple(self.kp_range),  # type: ignore[arg-type]
            ti_range=None if self.ti_range is None else tuple(self.ti_range),  # type: ignore[arg-type]
            derivative_filter=self.derivative_filter,
            model=None if self.model is None else tuple(self.model),
            heater=self.heater,
            sensor=self.sensor,
        )


class ModeIn(In):
    """Switch the run's controller: ``auto`` (bumpless from the input in force; a set point
    given with it is a step) or ``manual`` (holds the PID's last output unless ``u`` is given)."""

    mode: Literal["manual", "auto"]
    setpoint: float | None = Field(default=None, description="auto: a new set point")
    u: float | None = Field(default=None, description="manual: the input to hold")


class SetpointIn(In):
    """A new set point, in the rig's output unit."""

    setpoint: float


class FanIn(In):
    """The disturbance fan, % of full speed (rigs whose kind has one: the twins)."""

    percent: float = Field(json_schema_extra={"minimum": 0, "maximum": 100})


class LoopOut(Out):
    """A rig's closed-loop facts and its run's control loop now."""

    rig: str
    output_unit: str
    input_unit: str
    input_range: list[float]
    safe_input: float = Field(description="the input the rig rests at (a manual start's default)")
    output_limit: float | None
    closed_loop: bool = Field(description="the rig can be controlled (it has an output unit)")
    fan: dict[str, Any] | None = Field(description="the disturbance fan (unit, range), or null")
    pairs: list[dict[str, Any]] = Field(
        default_factory=list,
        description="the heater and sensor pairs a closed loop may control, the run's own "
        "(u, y) first: heater, sensor, inputUnit, inputRange, outputUnit, outputLimit "
        "(a kit: u/y and q2/t2; the panel offers a choice when there are more than one)",
    )
    loop: dict[str, Any] | None = Field(
        description="the current run's loop (mode, setpoint, gains, pid, adaptive with "
        "last_reason: why it holds the gains), or null"
    )
