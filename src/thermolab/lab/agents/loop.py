"""A remote rig's closed loop as the lab sees it: commands checked here, applied on the host.

:class:`RemoteLoop` stands in for the run's :class:`~thermolab.runner.Experiment`
in :func:`thermolab.lab.runs.commands.send_command` (it is a
:class:`~thermolab.runner.LoopCommands`): each command is checked against a
copy of the run's :class:`~thermolab.runner.ControlLoop`, bound to the rig as
published (the same set-point, input and fan checks, so the same 4xx codes),
then sent to the host, whose runner applies it from its next sample on. A
command the host still refuses (the run ended meanwhile) is logged there.

A run adopted by a new owner worker (docs/fleet.md, "Takeover") has its loop
built again from its request with the commands recorded since folded in
(:func:`commanded_request`): until the host's first heartbeat to the new
owner tells the loop, the loop route answers what the lab last commanded,
not the loop as started.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace
from typing import Any

from thermolab.agent.protocol import (
    LoopCommand,
    SetChannel,
    SetFan,
    SetGains,
    SetMode,
    SetSetpoint,
)
from thermolab.control import PIDGains
from thermolab.errors import HostOfflineError, InvalidParameterError
from thermolab.rigs import RigInfo
from thermolab.runner import ControlLoop, Interlocks
from thermolab.runner.control_request import ControlRequest
from thermolab.runner.control_requests import fan_level, refuse_loop_heater

__all__ = ["RemoteLoop", "commanded_request"]


def commanded_request(
    request: ControlRequest, commands: Iterable[tuple[str, Mapping[str, Any] | None]]
) -> ControlRequest:
    """``request`` as the run's recorded loop commands left it, in order.

    ``commands`` are ``(kind, payload)`` as :func:`~thermolab.lab.runs.commands.send_command`
    recorded them: ``setpoint`` (``{"setpoint"}``), ``gains`` (``PIDGains.to_dict``),
    ``mode`` (``{"mode", "setpoint"?, "u"?}``); others (``fan``, inputs) leave the loop as
    it is. An adaptive loop's own retunes are the host's: only its heartbeats tell them.

    Examples
    --------
    >>> start = ControlRequest(setpoint=35.0, kp=4.0, ti=140.0)
    >>> after = commanded_request(
    ...     start, [("setpoint", {"setpoint": 30.0}), ("mode", {"mode": "manual", "u": 20.0})]
    ... )
    >>> after.setpoint, after.mode, after.kp
    (30.0, 'manual', 4.0)
    """
    for kind, payload in commands:
        given = dict(payload or {})
        if kind == "setpoint":
            request = replace(request, setpoint=float(given["setpoint"]))
        elif kind == "gains":
            request = replace(
                request, kp=float(given["Kp"]), ti=float(given["Ti"]), td=float(given["Td"])
            )
        elif kind == "mode":
            request = replace(request, mode=str(given["mode"]))
            if given.get("setpoint") is not None:
                request = replace(request, setpoint=float(given["setpoint"]))
    return request


class RemoteLoop:
    """The closed-loop commands of run ``run_id`` on a rig host.

    Parameters
    ----------
    run_id : int
    loop : ControlLoop or None
        The run's loop as START built it (bound to ``info``); ``None``: an open-loop run.
    info : RigInfo
        The rig as published.
    fan : bool
        Whether the rig has a disturbance fan.
    send : callable
        Sends a command to the host; ``False`` when it is not connected.
    """

    def __init__(
        self,
        run_id: int,
        loop: ControlLoop | None,
        info: RigInfo,
        fan: bool,
        send: Callable[[LoopCommand], bool],
    ) -> None:
        self._run = run_id
        self._loop = loop
        self._info = info
        self._fan = fan
        self._send = send

    @property
    def controller(self) -> ControlLoop | None:
        """The run's loop as started (its checks), ``None`` for an open-loop run."""
        return self._loop

    def set_auto(self, setpoint: float | None = None) -> None:
        """Switch the host's controller to AUTO (a set point checked first)."""
        if setpoint is not None:
            setpoint = self._require().check_setpoint(setpoint)
        self._forward(SetMode(run=self._run, auto=True, setpoint=setpoint))

    def set_manual(self, u: float | None = None) -> None:
        """Switch the host's controller to MANUAL (``u`` checked against the input range)."""
        loop = self._require()
        if u is not None and loop.drives_further:
            self._info.further_level(loop.heater, u)
        elif u is not None:
            problem = Interlocks.check_input(float(u), self._info)
            if problem is not None:
                raise InvalidParameterError(problem)
        self._forward(SetMode(run=self._run, auto=False, u=u))

    def set_setpoint(self, setpoint: float) -> None:
        """Change the host's set point (checked against the rig's output range)."""
        r = self._require().check_setpoint(setpoint)
        self._forward(SetSetpoint(run=self._run, setpoint=r))

    def set_gains(self, gains: PIDGains) -> None:
        """Change the host's gains (``PIDGains`` checked them)."""
        self._require()
        self._forward(SetGains(run=self._run, gains=gains))

    def set_fan(self, percent: float) -> None:
        """Run the rig's disturbance fan (a rig without one: 422)."""
        level = fan_level(self._info, self._fan, percent)
        self._forward(SetFan(run=self._run, percent=level))

    def set_further(self, name: str, value: float) -> None:
        """Set the rig's further input ``name`` (a rig without it, a level out of range: 422)."""
        level = self._info.further_level(name, value)
        refuse_loop_heater(self._loop, name)
        self._forward(SetChannel(run=self._run, name=name, level=level))

    def _require(self) -> ControlLoop:
        if self._loop is None:  # send_command refuses first; kept for direct callers
            raise InvalidParameterError("this run has no controller")
        return self._loop

    def _forward(self, command: LoopCommand) -> None:
        if not self._send(command):
            raise HostOfflineError(
                f"the host of rig {self._info.name!r} is offline; try again later"
            )
