"""The closed-loop requests of a run: AUTO/MANUAL, set point, gains, the disturbance fan.

:class:`ControlRequests` is the part of :class:`~thermolab.runner.Experiment`
that talks to its :class:`~thermolab.runner.closed_loop.ControlLoop` (kept
apart so that the sampling loop's module stays readable). Every request is
thread-safe and takes effect at the next sample; the interlocks and the safe
state are the sampling loop's and still win.
"""

from __future__ import annotations

import math
import threading
from typing import Protocol

from thermolab.control import PIDGains
from thermolab.errors import ChannelInLoopError, InvalidParameterError
from thermolab.records import ChannelSpec
from thermolab.rigs import RigInfo
from thermolab.runner.closed_loop import ControlLoop
from thermolab.runner.inputs import ChannelSource

__all__ = [
    "FAN_CHANNEL",
    "ControlRequests",
    "LoopCommands",
    "closed_loop_channels",
    "fan_level",
    "fan_source",
    "refuse_loop_heater",
]

#: The disturbance fan's channel (recorded by a closed-loop run on a rig with a fan).
FAN_CHANNEL = ChannelSpec("fan", "%", "other", "disturbance fan, % of full speed")


def fan_source(rig: object) -> ChannelSource:
    """The fan's channel and its level, read from the rig at each sample (NaN if it cannot say)."""
    return (FAN_CHANNEL, lambda t, u, y: float(getattr(rig, "fan", math.nan)))


def closed_loop_channels(
    rig: object, loop: ControlLoop, *, fan: bool | None = None
) -> tuple[ChannelSpec, ...]:
    """The channels a closed-loop run adds after ``RUN_CHANNELS`` (``loop`` bound first).

    The loop's (``r, u_pid, e, auto``...), then ``fan`` when the rig has a
    disturbance fan (``fan``: whether it has, for a rig known by its spec
    only, e.g. a rig host's): what a recorder of the run must declare.
    """
    has_fan = callable(getattr(rig, "set_fan", None)) if fan is None else fan
    return (*loop.channels(), *((FAN_CHANNEL,) if has_fan else ()))


def fan_level(info: RigInfo, has_fan: bool, percent: float) -> float:
    """Return ``percent`` as a fan level for the rig ``info``.

    Raises
    ------
    InvalidParameterError
        If the rig has no disturbance fan or ``percent`` is not in [0, 100].
    """
    if not has_fan:
        raise InvalidParameterError(f"rig {info.name!r} has no disturbance fan")
    try:
        level = float(percent)
    except (TypeError, ValueError):
        raise InvalidParameterError(f"the fan takes 0-100 %, got {percent!r}") from None
    if not (math.isfinite(level) and 0.0 <= level <= 100.0):
        raise InvalidParameterError(f"the fan takes 0-100 %, got {percent!r}")
    return level


def refuse_loop_heater(loop: ControlLoop | None, name: str) -> None:
    """Refuse a hand setting of the further input ``name`` if the run's loop drives it.

    Raises
    ------
    ChannelInLoopError
        ``loop`` drives ``name`` (409 ``channel_in_loop``): its PID sets it;
        the other heater stays settable by hand, as a disturbance.
    """
    if loop is not None and loop.drives_further and loop.heater == name:
        raise ChannelInLoopError(
            f"{name} is driven by this run's closed loop (its PID sets it from {loop.sensor}); "
            f"to hold {name} at a level of your own, switch the loop to manual with that input"
        )


class LoopCommands(Protocol):
    """What a closed-loop command acts on: a run's :class:`~thermolab.runner.Experiment`,
    or a stand-in that checks the command as the run would and forwards it (a rig host's run).
    """

    @property
    def controller(self) -> ControlLoop | None:
        """The control loop (``None``: an open-loop run)."""
        ...

    def set_auto(self, setpoint: float | None = None) -> None:
        """Switch to AUTO (see :meth:`ControlRequests.set_auto`)."""
        ...

    def set_manual(self, u: float | None = None) -> None:
        """Switch to MANUAL (see :meth:`ControlRequests.set_manual`)."""
        ...

    def set_setpoint(self, setpoint: float) -> None:
        """Change the set point (see :meth:`ControlRequests.set_setpoint`)."""
        ...

    def set_gains(self, gains: PIDGains) -> None:
        """Change the gains (see :meth:`ControlRequests.set_gains`)."""
        ...

    def set_fan(self, percent: float) -> None:
        """Run the disturbance fan (see :meth:`ControlRequests.set_fan`)."""
        ...

    def set_further(self, name: str, value: float) -> None:
        """Set a further input (see :meth:`ControlRequests.set_further`)."""
        ...


class ControlRequests:
    """Mixed into :class:`~thermolab.runner.Experiment`: requests to its control loop."""

    _control: ControlLoop | None
    _info: RigInfo
    _fan_request: float | None
    _further_requests: dict[str, float]
    _loop_level: float
    _request_lock: threading.Lock

    def set_input(self, u: float) -> None:  # the experiment's
        raise NotImplementedError

    def _refuse_when_over(self, action: str) -> None:  # the experiment's
        raise NotImplementedError

    @property
    def controller(self) -> ControlLoop | None:
        """The control loop, or ``None`` for an open-loop run."""
        return self._control

    def _require_control(self, action: str) -> ControlLoop:
        if self._control is None:
            raise InvalidParameterError(
                f"cannot {action}: this run has no controller (Experiment(controller=...))"
            )
        self._refuse_when_over(action)
        return self._control

    def set_auto(self, setpoint: float | None = None) -> None:
        """Switch the controller to AUTO from the next sample on, without a bump.

        Parameters
        ----------
        setpoint : float, optional
            A new set point (output unit); default: the one in force.

        Raises
        ------
        InvalidParameterError
            If the run has no controller or the set point is not valid.
        RunStateError
            If the run is already over.
        """
        control = self._require_control("switch to automatic")
        if setpoint is not None:
            control.request_setpoint(setpoint)
        control.request_auto()

    def set_manual(self, u: float | None = None) -> None:
        """Switch the controller to MANUAL; hold its last output unless ``u`` is given.

        Holding the last output is the bumpless transfer from AUTO to MANUAL.
        A loop on a further pair (a kit's ``q2``/``t2``) holds its own heater
        there; the run's input ``u`` stays as it is.

        Raises
        ------
        InvalidParameterError
            If the run has no controller or ``u`` is not a valid input.
        RunStateError
            If the run is already over.
        """
        control = self._require_control("switch to manual")
        held = control.output if u is None else u
        if control.drives_further:
            # The loop's own heater holds the level; the run's input u is not the loop's.
            if u is None and not math.isfinite(held):
                held = self._info.inputs[control.heater].default  # nothing applied yet
            self._loop_level = self._info.further_level(control.heater, held)
            control.request_manual()
            return
        if u is None and not math.isfinite(held):
            held = self._info.safe_input  # nothing applied yet
        self.set_input(held)

    def set_setpoint(self, setpoint: float) -> None:
        """Change the controller's set point (output unit) from the next sample on.

        Raises
        ------
        InvalidParameterError
            If the run has no controller or the set point is outside the rig's
            output range.
        RunStateError
            If the run is already over.
        """
        self._require_control("change the set point").request_setpoint(setpoint)

    def set_gains(self, gains: PIDGains) -> None:
        """Change the PID's gains from the next sample on, without a bump.

        Raises
        ------
        InvalidParameterError
            If the run has no controller or ``gains`` is not :class:`PIDGains`.
        RunStateError
            If the run is already over.
        """
        self._require_control("change the gains").request_gains(gains)

    def set_fan(self, percent: float) -> None:
        """Run the rig's disturbance fan at ``percent`` from the next sample on.

        The fan is a disturbance, not the controlled input: it is set at the
        sample's instant (``rig.set_fan(percent, at=...)``), and the run
        records it as the ``fan`` channel when the rig has one.

        Raises
        ------
        InvalidParameterError
            If the rig has no disturbance fan or ``percent`` is not in [0, 100].
        RunStateError
            If the run is already over.
        """
        level = fan_level(self._info, self.has_fan, percent)
        self._refuse_when_over("set the fan")
        self._fan_request = level

    def set_further(self, name: str, value: float) -> None:
        """Set the rig's further input ``name`` (a kit's heater 2) from the next sample on.

        Like the fan, a further input is not the run's input ``u``: it is set
        at the sample's instant (``rig.set_channel(name, value, at=...)``), in
        an open or a closed loop, and the run records its level when the rig
        declares it ``recorded`` (:func:`thermolab.runner.further.further_channels`).
        The input a closed loop drives (:attr:`ControlLoop.heater`) is its PID's.

        Raises
        ------
        InvalidParameterError
            If the rig has no such input or ``value`` is outside its range.
        ChannelInLoopError
            If the run's closed loop drives ``name``.
        RunStateError
            If the run is already over.
        """
        level = self._info.further_level(name, value)
        refuse_loop_heater(self._control, name)
        self._refuse_when_over(f"set {name}")
        with self._request_lock:
            self._further_requests[name] = level

    @property
    def has_fan(self) -> bool:
        """Whether the rig has a disturbance fan (``set_fan``)."""
        return callable(getattr(getattr(self, "_rig", None), "set_fan", None))
