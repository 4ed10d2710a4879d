"""PID control in the experiment loop: the mode, the set point and the recorded channels.

:class:`ControlLoop` is what :class:`~thermolab.runner.Experiment` drives
(``Experiment(..., controller=ControlLoop(...))``): once per sample, after the
output is read and checked against the interlocks, :meth:`ControlLoop.command`
turns the open-loop input (the manual value or the signal) into the input to
apply — the PID's output in AUTO, the open-loop input in MANUAL, which the
PID then tracks so that switching back to AUTO makes no bump — and, after the
input is applied, :meth:`ControlLoop.after` feeds the adaptive tuner and gives
the values of the control channels (``r``, ``u_pid``, ``e``, ``auto`` and, when
adaptive, ``kp``, ``ti``, ``td``).

Switching is requested from any thread (:meth:`request_auto`,
:meth:`request_manual`, :meth:`request_setpoint`, :meth:`request_gains`) and
takes effect at the next sample; the law itself is
:class:`thermolab.control.PID` (numerics, no threads).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from thermolab.control import PID, AdaptiveTuner, GainBounds, PIDGains
from thermolab.errors import InvalidParameterError, NoOutputUnitError, SetpointRangeError
from thermolab.records import ChannelSpec
from thermolab.rigs import PRIMARY_PAIR, RigInfo
from thermolab.runner.interlocks import Interlocks

__all__ = ["ControlLoop", "SetpointProfile", "adaptive_tuner", "estimate_trust"]


def estimate_trust(dt: float, expected_sign: int) -> Any:
    """The adaptive tuner's check of an online estimate, from :mod:`thermolab.ident`.

    Returns ``trust(estimate) -> reason or None``: the estimate's own warnings
    (``extras["warnings"]``) and :func:`thermolab.ident.diagnostics.plausibility_warnings`
    over the record so far (a time constant under two periods, a gain of the
    wrong sign: the plant's is the sign of the gains in force).
    """
    from thermolab.ident.diagnostics import plausibility_warnings

    def trust(estimate: Any) -> str | None:
        extras = getattr(estimate, "extras", None) or {}
        warnings = list(extras.get("warnings") or ())
        duration = (int(getattr(estimate, "k", 0)) + 1) * dt
        warnings += plausibility_warnings(
            float(estimate.K), float(estimate.tau), dt, duration, expected_sign=expected_sign
        )
        return warnings[0] if warnings else None

    return trust


def adaptive_tuner(
    dt: float,
    gains: PIDGains,
    *,
    rule: str | None = None,
    form: str | None = None,
    tau_c: float | None = None,
    theta: float = 0.0,
    every: int | None = None,
    max_change: float | None = None,
    settle_tol: float | None = None,
    excitation: float | None = None,
    bounds: GainBounds | None = None,
) -> AdaptiveTuner:
    """An :class:`~thermolab.control.AdaptiveTuner` on live WLSM, trusting what ident trusts.

    ``None`` takes the declared default (:data:`thermolab.control.PARAMETERS`).
    The plant's sign is that of ``gains.Kp``.
    """
    from thermolab.control import PARAMETERS
    from thermolab.ident import make_identifier

    def given(name: str, value: Any) -> Any:
        return PARAMETERS[name].default if value is None else value

    return AdaptiveTuner(
        make_identifier("wlsm", dt),
        given("rule", rule),
        every=given("every", every),
        form=form,
        tau_c=tau_c,
        theta=theta,
        max_change=given("max_change", max_change),
        bounds=bounds,
        settle_tol=given("settle_tol", settle_tol),
        excitation=given("excitation", excitation),
        trust=estimate_trust(dt, 1 if gains.Kp > 0 else -1),
    )


@runtime_checkable
class SetpointProfile(Protocol):
    """A set point defined in time: anything with ``value(t) -> float`` (a Signal)."""

    def value(self, t: float) -> float:
        """Return the set point ``t`` seconds after START."""
        ...


class ControlLoop:
    """A PID on the rig's output, switchable between AUTO and MANUAL while a run goes.

    Parameters
    ----------
    gains : PIDGains
        The PID's gains.
    setpoint : float or InputSignal
        The set point in the rig's output unit: a number, or a profile in time
        since START (anything with ``value(t)``, e.g.
        ``parse_signal("step:21:50@100")`` for a set-point step at 100 s).
    auto : bool, optional
        Start in AUTO (default) or in MANUAL (the run's signal or manual input
        drives until :meth:`request_auto`).
    derivative_filter : float, optional
        ``N`` of the derivative filter (default 10).
    tuner : AdaptiveTuner, optional
        Retunes the gains from an online identifier (default: none, fixed gains).
    heater, sensor : str, optional
        The pair the loop controls, by the rig's names (:attr:`RigInfo.loop_pairs`):
        ``"u"``, ``"y"`` (default) the run's own input and output; a kit's
        ``"q2"``, ``"t2"`` its heater 2 from its sensor 2, the run's input ``u``
        (heater 1) then staying the open loop's, a disturbance set by hand.

    Notes
    -----
    Anti-windup is back-calculation (see :mod:`thermolab.control.pid`); the
    limits are the rig's input range, bound when the experiment is made.

    Transfers: in MANUAL the PID tracks the applied input at the set point in
    force, so MANUAL -> AUTO continues from that input without a bump (a set
    point given with the switch then steps, with its proportional kick);
    AUTO -> MANUAL by :meth:`Experiment.set_manual` holds the last output. A
    run that *starts* in AUTO treats its set point as a step from rest (the
    integral starts at the open-loop input), as :func:`predict_closed_loop`
    does.

    Examples
    --------
    >>> from thermolab.rigs import VirtualClock
    >>> from thermolab.rigs.twin import TwinRig
    >>> from thermolab.runner import Experiment
    >>> loop = ControlLoop(PIDGains(40.0, 250.0), setpoint=1.0)
    >>> with TwinRig("paper", clock=VirtualClock()) as rig:
    ...     result = Experiment(rig, dt=1.0, samples=1500, controller=loop).run()
    >>> round(float(result.y[-1]), 3), [c.name for c in result.channels][-4:]
    (1.0, ['u_pid', 'e', 'auto', 'fan'])
    """

    def __init__(
        self,
        gains: PIDGains,
        setpoint: float | SetpointProfile,
        *,
        auto: bool = True,
        derivative_filter: float = 10.0,
        tuner: AdaptiveTuner | None = None,
        heater: str = PRIMARY_PAIR[0],
        sensor: str = PRIMARY_PAIR[1],
    ) -> None:
        if not isinstance(gains, PIDGains):
            raise InvalidParameterError(f"gains must be PIDGains, got {type(gains).__name__}")
        if tuner is not None and not isinstance(tuner, AdaptiveTuner):
            raise InvalidParameterError(
                f"tuner must be an AdaptiveTuner, got {type(tuner).__name__}"
            )
        self._initial_gains = gains
        self._profile: SetpointProfile | None = None
        if isinstance(setpoint, SetpointProfile):
            self._profile = setpoint
            self._setpoint = self._finite_setpoint(setpoint.value(0.0))
        else:
            self._setpoint = self._finite_setpoint(setpoint)
        self._auto = bool(auto)
        self._derivative_filter = derivative_filter
        self.tuner = tuner
        self._pid: PID | None = None
        self._info: RigInfo | None = None
        self._interlocks = Interlocks()
        self._started = False
        # Requests from other threads, applied at the next sample.
        self._want_auto: bool | None = None
        self._want_gains: PIDGains | None = None
        self._switches = 0
        self._last_r: float | None = None
        self._pair = (str(heater), str(sensor))
        # The pair's ranges and units (bind): the rig's input and output, or a further pair's.
        self._limits = (-math.inf, math.inf)
        self._units = ("", "")
        self._output_limit: float | None = None

    # -- binding to a rig -------------------------------------------------------------------

    def bind(self, info: RigInfo, interlocks: Interlocks, times: Sequence[float] = ()) -> None:
        """Check the loop against a rig and make its PID (the experiment calls this).

        Parameters
        ----------
        info : RigInfo
        interlocks : Interlocks
        times : sequence of float, optional
            The run's sample times, at which a set-point profile is checked.

        Raises
        ------
        InvalidParameterError
            If the rig has no output unit, or the set point is outside the
            rig's output range (its output limit and the interlocks).
        LoopPairNotOnRigError
            If the rig has no such heater and sensor pair.
        """
        heater, sensor = info.check_loop_pair(*self._pair)
        if heater == PRIMARY_PAIR[0]:
            self._limits = (info.input_min, info.input_max)
            self._units = (info.input_unit, info.output_unit)
            self._output_limit = info.output_limit
        else:
            channel, output = info.inputs[heater], info.outputs[sensor]
            self._limits = channel.range
            self._units = (channel.unit, output.unit)
            self._output_limit = output.limit
        if not self._units[1]:
            raise NoOutputUnitError(
                f"rig {info.name!r} has no output unit: PID control needs a measured output"
            )
        self._info = info
        self._interlocks = interlocks
        self.check_setpoint(self._setpoint)
        profile = self._profile
        if profile is not None and len(times):
            sample = getattr(profile, "sample", None)
            values = (
                np.asarray(sample(np.asarray(times, dtype=np.float64)), dtype=np.float64)
                if callable(sample)
                else np.array([profile.value(t) for t in times], dtype=np.float64)
            )
            if not np.isfinite(values).all():
                raise InvalidParameterError("the set-point profile must be finite at every sample")
            self.check_setpoint(float(values.min()))
            self.check_setpoint(float(values.max()))
        # A loop bound again (a new run) starts afresh.
        self._started = False
        self._last_r = None
        self._want_auto = self._want_gains = None
        if self.tuner is not None:
            self.tuner.set_input_range(*self._limits)
        self._pid = PID(
            self._initial_gains,
            *self._limits,
            derivative_filter=self._derivative_filter,
        )

    def channels(self) -> tuple[ChannelSpec, ...]:
        """The channels this loop records, in order (after :meth:`bind`)."""
        self._require_info()
        inp, out = self._units
        specs = [
            ChannelSpec("r", out, "setpoint", "set point of the PID"),
            ChannelSpec("u_pid", inp, "other", "the PID's output (tracks the input in manual)"),
            ChannelSpec("e", out, "error", "control error r - y"),
            ChannelSpec("auto", "", "other", "1 in automatic (PID), 0 in manual", integer=True),
        ]
        if self.tuner is not None:
            specs += [
                ChannelSpec("kp", f"{inp}/{out}", "other", "proportional gain in force"),
                ChannelSpec("ti", "s", "other", "integral time in force"),
                ChannelSpec("td", "s", "other", "derivative time in force"),
            ]
        return tuple(specs)

    # -- state -----------------------------------------------------------------------------

    @property
    def heater(self) -> str:
        """The input the loop drives: ``"u"``, the run's own, or a further input (``"q2"``)."""
        return self._pair[0]

    @property
    def sensor(self) -> str:
        """The output the loop controls: ``"y"``, the run's own, or a further output (``"t2"``)."""
        return self._pair[1]

    @property
    def drives_further(self) -> bool:
        """``True`` when the loop drives a further input, not the run's input ``u``."""
        return self._pair[0] != PRIMARY_PAIR[0]

    @property
    def input_range(self) -> tuple[float, float]:
        """The range of the input the loop drives (after :meth:`bind`)."""
        return self._limits

    @property
    def setpoint(self) -> float:
        """The set point in force (output unit)."""
        return self._setpoint

    @property
    def auto(self) -> bool:
        """``True`` in AUTO (the PID drives), ``False`` in MANUAL."""
        return self._auto

    @property
    def initial_gains(self) -> PIDGains:
        """The gains the loop was made with (before any change or retune)."""
        return self._initial_gains

    @property
    def derivative_filter(self) -> float:
        """``N`` of the PID's derivative filter."""
        return self._derivative_filter

    @property
    def gains(self) -> PIDGains:
        """The gains in force."""
        return self._initial_gains if self._pid is None else self._pid.gains

    @property
    def output(self) -> float:
        """The PID's last output (the input it applied, or tracked in MANUAL)."""
        return math.nan if self._pid is None else self._pid.output

    def check_setpoint(self, value: float) -> float:
        """Return ``value`` if it is a valid set point for the bound rig.

        Raises
        ------
        InvalidParameterError
            If it is not finite, or not below the rig's output limit and within
            the interlocks' output range.
        """
        r = self._finite_setpoint(value)
        if self._info is None:
            return r
        unit = self._units[1]
        # The interlocks guard the run's output y; a further sensor has its own limit.
        own = not self.drives_further
        interlock_max = self._interlocks.output_max if own else None
        high = [x for x in (self._output_limit, interlock_max) if x is not None]
        low = self._interlocks.output_min if own else None
        if (high and r >= min(high)) or (low is not None and r <= low):
            allowed = (
                f"({'-inf' if low is None else f'{low:g}'}, {min(high) if high else math.inf:g})"
            )
            raise SetpointRangeError(
                f"set point {r:g} {unit} is outside the rig's output range {allowed} {unit}"
            )
        return r

    # -- requests (any thread) --------------------------------------------------------------

    def request_setpoint(self, value: float) -> None:
        """Hold the set point at ``value`` from the next sample on (ends a profile)."""
        r = self.check_setpoint(value)
        self._profile = None
        self._setpoint = r

    def request_auto(self) -> None:
        """Switch to AUTO at the next sample, bumplessly from the input in force."""
        self._want_auto = True

    def request_manual(self) -> None:
        """Switch to MANUAL at the next sample (the experiment sets the manual input)."""
        self._want_auto = False

    def request_gains(self, gains: PIDGains) -> None:
        """Change the gains at the next sample, without a bump in the output."""
        if not isinstance(gains, PIDGains):
            raise InvalidParameterError(f"gains must be PIDGains, got {type(gains).__name__}")
        self._want_gains = gains

    # -- the sampling loop's side ------------------------------------------------------------

    def command(self, y: float, u_open: float, dt: float, t: float) -> float:
        """The input to apply at sample time ``t``: the PID's in AUTO, ``u_open`` in MANUAL."""
        pid = self._pid
        assert pid is not None, "bind() first"
        profile = self._profile
        if profile is not None:
            self._setpoint = float(profile.value(t))
        r = self._setpoint
        previous_r = r if self._last_r is None else self._last_r
        self._last_r = r
        switched = False
        want = self._want_auto
        if want is not None:
            self._want_auto = None
            if want != self._auto:
                self._auto = want
                self._switches += 1
                switched = True
        gains = self._want_gains
        if gains is not None:
            self._want_gains = None
            pid.set_gains(gains, r, y)
        if not self._auto:
            pid.track(u_open, r, y)
            return u_open
        if not self._started:
            # A run that starts in AUTO is a set-point step from rest: the integral holds
            # the open-loop input, the proportional part acts on the whole error.
            pid.track(u_open, y, y)
        elif switched:
            # Bumpless MANUAL -> AUTO: the output continues from the manual input at the
            # set point in force before; a set point given with the switch is then a step.
            pid.track(u_open, previous_r, y)
        self._started = True
        return pid.update(r, y, dt)

    def after(self, u: float, y: float) -> tuple[float, ...]:
        """Record the applied input; return the control channels' values at this sample."""
        pid = self._pid
        assert pid is not None, "bind() first"
        self._started = True
        if self.tuner is not None:
            retuned = self.tuner.update(u, y, pid.gains)
            if retuned is not None:
                self._want_gains = retuned
        r = self._setpoint
        values: tuple[float, ...] = (r, u, r - y, 1.0 if self._auto else 0.0)
        if self.tuner is not None:
            g = pid.gains
            values += (g.Kp, g.Ti, g.Td)
        return values

    def to_dict(self) -> dict[str, Any]:
        """Return the mode, set point, gains and PID state (JSON-ready)."""
        return {
            "heater": self._pair[0],
            "sensor": self._pair[1],
            "mode": "auto" if self._auto else "manual",
            "setpoint": self._setpoint,
            "setpoint_profile": None
            if self._profile is None
            else getattr(self._profile, "spec", type(self._profile).__name__),
            "switches": self._switches,
            "gains": self.gains.to_dict(),
            "pid": None if self._pid is None else self._pid.to_dict(),
            "adaptive": None if self.tuner is None else self.tuner.to_dict(),
        }

    def _require_info(self) -> RigInfo:
        if self._info is None:
            raise InvalidParameterError("the control loop is not bound to a rig yet")
        return self._info

    @staticmethod
    def _finite_setpoint(value: float) -> float:
        try:
            r = float(value)
        except (TypeError, ValueError):
            raise InvalidParameterError(f"the set point must be a number, got {value!r}") from None
        if not math.isfinite(r):
            raise InvalidParameterError(f"the set point must be finite, got {value!r}")
        return r
