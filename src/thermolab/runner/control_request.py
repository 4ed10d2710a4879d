"""What a closed-loop run asks of its controller, and its one check.

A run may carry a :class:`ControlRequest` (``"control"`` in ``RunIn``): a PID
on the rig's output in MANUAL or AUTO, its gains, the set point, and
optionally adaptive retuning. Every range is the control layer's declaration
(:data:`thermolab.control.PARAMETERS`); :func:`build_control_loop` checks the
request once, against those and the rig (a set point outside its output range,
a rig with no output unit), before anything is stored, and builds the
:class:`~thermolab.runner.ControlLoop` the run drives. Declared here, in the
runner, so that the lab (before anything is stored) and a rig host (for a
remote rig's run, :class:`thermolab.agent.protocol.StartRun` carries the
request as it is) build the same loop from the same request.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from thermolab.control import FOPDT, PARAMETERS, GainBounds, PIDGains
from thermolab.errors import InvalidParameterError, SetpointRangeError
from thermolab.rigs import PRIMARY_PAIR, RigInfo
from thermolab.runner.closed_loop import ControlLoop, adaptive_tuner
from thermolab.runner.interlocks import Interlocks

__all__ = ["CONTROL_MODES", "ControlRequest", "build_control_loop"]

#: How a closed-loop run starts: the PID drives (``auto``) or tracks the manual input.
CONTROL_MODES: tuple[str, ...] = ("manual", "auto")


@dataclass(frozen=True, slots=True)
class ControlRequest:
    """The controller of a closed-loop run (every range: :data:`thermolab.control.PARAMETERS`).

    Attributes
    ----------
    mode : {"manual", "auto"}
        AUTO: the PID drives from the first sample; MANUAL: the run's signal or
        set point drives and the PID tracks it until switched.
    setpoint : float
        The controlled output's set point, in the rig's output unit.
    kp, ti, td : float
        The gains (``td`` default 0: a PI).
    adaptive : bool
        Retune live from WLSM (off by default).
    rule, form, tau_c, every, max_change, settle_tol, excitation, kp_range, ti_range
        The adaptive tuner's settings (``None``: the declared default).
    derivative_filter : float or None
        ``N`` of the derivative filter.
    model : tuple of float or None
        ``(K, tau, theta)`` the gains were tuned from (the prediction shown
        beside the measured run).
    heater, sensor : str
        The pair the PID controls, by the rig's names
        (:attr:`thermolab.rigs.RigInfo.loop_pairs`): ``"u"``, ``"y"`` (default)
        the run's own input and output; a kit's ``"q2"``, ``"t2"`` its heater 2
        from its sensor 2 (heater 1 is then the run's input, set by hand as a
        disturbance). Stored with the run, so its record says which pair.
    """

    setpoint: float
    kp: float
    ti: float
    td: float = 0.0
    mode: str = "auto"
    adaptive: bool = False
    rule: str | None = None
    form: str | None = None
    tau_c: float | None = None
    every: int | None = None
    max_change: float | None = None
    settle_tol: float | None = None
    excitation: float | None = None
    kp_range: tuple[float, float] | None = None
    ti_range: tuple[float, float] | None = None
    derivative_filter: float | None = None
    model: tuple[float, ...] | None = None
    heater: str = PRIMARY_PAIR[0]
    sensor: str = PRIMARY_PAIR[1]

    def settings(self) -> dict[str, Any]:
        """The request as stored with the run."""
        out = {name: getattr(self, name) for name in self.__slots__}
        for name in ("kp_range", "ti_range", "model"):
            if out[name] is not None:
                out[name] = list(out[name])
        return out

    def gains(self) -> PIDGains:
        """The starting gains (checked against the published ranges)."""
        return PIDGains(self.kp, self.ti, self.td)

    def fopdt(self) -> FOPDT | None:
        """The model the gains came from, if given."""
        return None if self.model is None else FOPDT(*self.model)


_TUNER_SETTINGS = (
    "rule", "form", "tau_c", "every", "max_change", "settle_tol", "excitation", "kp_range",
    "ti_range",
)  # fmt: skip


def _check(request: ControlRequest) -> None:
    if request.mode not in CONTROL_MODES:
        raise InvalidParameterError(
            f"mode must be one of {', '.join(CONTROL_MODES)}, got {request.mode!r}"
        )
    for name in ("kp", "ti", "td", "derivative_filter", *_TUNER_SETTINGS):
        PARAMETERS[name].check(getattr(request, name))
    if not request.adaptive:
        given = [n for n in _TUNER_SETTINGS if getattr(request, n) is not None]
        if given:
            raise InvalidParameterError(f"{', '.join(given)}: adaptive settings need adaptive")
    if request.model is not None and len(request.model) not in (2, 3):
        raise InvalidParameterError(f"model is [K, tau] or [K, tau, theta], got {request.model!r}")
    request.fopdt()


def build_control_loop(
    request: ControlRequest, dt: float, times: Sequence[float], info: RigInfo
) -> ControlLoop:
    """Check a closed-loop request against the declared ranges and the rig; build its loop.

    Raises
    ------
    GainRangeError
        A gain or setting not finite or outside its published range.
    SetpointRangeError
        The set point outside the rig's output range.
    NoOutputUnitError
        The rig has no output unit.
    LoopPairNotOnRigError
        The rig has no such heater and sensor pair.
    InvalidParameterError
        Any other bad value (mode, model).
    """
    _check(request)
    gains = request.gains()
    tuner = None
    if request.adaptive:
        bounds = GainBounds(
            **{
                name: value
                for name, value in (("kp", request.kp_range), ("ti", request.ti_range))
                if value is not None
            }
        )
        model = request.fopdt()
        tuner = adaptive_tuner(
            dt,
            gains,
            rule=request.rule,
            form=request.form,
            tau_c=request.tau_c,
            theta=0.0 if model is None else model.theta,
            every=request.every,
            max_change=request.max_change,
            settle_tol=request.settle_tol,
            excitation=request.excitation,
            bounds=bounds,
        )
    if not math.isfinite(request.setpoint):
        raise SetpointRangeError(f"the set point must be finite, got {request.setpoint!r}")
    loop = ControlLoop(
        gains,
        request.setpoint,
        auto=request.mode == "auto",
        derivative_filter=PARAMETERS["derivative_filter"].default
        if request.derivative_filter is None
        else request.derivative_filter,
        tuner=tuner,
        heater=request.heater,
        sensor=request.sensor,
    )
    loop.bind(info, Interlocks(), times)
    return loop
