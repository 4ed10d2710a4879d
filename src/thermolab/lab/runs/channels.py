"""A controller sets a rig's further input (a kit's heater 2): in its run, or on the idle rig.

``PUT /api/rigs/{rig}/channels/{name}`` lands here. The rig's declared
further inputs (:attr:`thermolab.rigs.RigInfo.further_inputs`) say what may be
set and within what range (422 before anything else). During a run the level
goes to the run as a command, as the disturbance fan's does
(:func:`thermolab.lab.runs.commands.send_command`: the controller of the
run's turn only, applied at the next sample, recorded); with no run, only the
controller sets it, the command is recorded, and the hub applies it to the
device (a rig host's idle rig: its host, told by the agent hub). Either way
the rig's safe state puts it back at its default at the end of the run and of
the turn (issue #23).
"""

from __future__ import annotations

from collections.abc import Container
from dataclasses import dataclass
from typing import Protocol

from thermolab.lab.access import AccessService
from thermolab.lab.accounts.users import Principal
from thermolab.lab.config import LabConfig
from thermolab.lab.rigs.devices import DeviceHub
from thermolab.lab.runs.commands import CHANNEL_COMMAND
from thermolab.lab.runs.store import run_command
from thermolab.lab.runs.where import RunsByRig

__all__ = ["ChannelResult", "RigHosts", "set_channel"]


class RigHosts(Protocol):
    """The rig hosts as a further input's level needs them (the lab's agent hub).

    A protocol, not the hub itself: the runs know no rig host's socket
    (:class:`~thermolab.lab.runs.where.RunsByRig` says the same of a run).
    """

    def set_channel(self, rig_id: str, name: str, level: float) -> bool:
        """Tell the idle rig's host to set ``name`` at ``level``; whether a host took it."""


@dataclass(frozen=True, slots=True)
class ChannelResult:
    """A further input's level as the lab handled it.

    Attributes
    ----------
    rig_id, name : str
    level : float
        The level asked for (checked against the channel's range).
    applied : float or None
        The level set: by the device, or the run's next sample; ``None`` when
        it reached no device (the rig is off, on a rig host outside a run).
    run_id : int or None
        The run it went to, if one was going.
    """

    rig_id: str
    name: str
    level: float
    applied: float | None
    run_id: int | None


def set_channel(
    config: LabConfig,
    access: AccessService,
    hub: DeviceHub,
    runs: RunsByRig,
    hosts: tuple[RigHosts, Container[str]],
    rig_id: str,
    who: Principal,
    name: str,
    value: float,
) -> ChannelResult:
    """Set the rig's further input ``name`` at ``value`` for its controller ``who``.

    ``hosts``: the lab's rig hosts and the rigs they serve (an idle hosted rig
    gets the level through its host).

    Raises
    ------
    NotFoundError
        For an unknown rig.
    ChannelNotOnRigError
        If the rig does not declare the input (422 ``channel_not_on_rig``).
    InvalidParameterError
        If ``value`` is outside the input's range (422).
    AccessDeniedError
        If ``who`` does not control the rig (or the run belongs to an earlier turn).
    """
    level = config.rig(rig_id).rig_spec.describe().further_level(name, value)
    payload = {"name": name, "level": level}
    run_id = runs.running(rig_id)
    if run_id is not None:
        record = runs.command(
            rig_id,
            who,
            CHANNEL_COMMAND,
            payload,
            lambda experiment: experiment.set_further(name, level),
        )
        return ChannelResult(rig_id, name, level, level, record.id)
    with access.controlled(rig_id, who, f"set {name}") as turn:
        turn.session.add(
            run_command(rig_id, turn.control, who, turn.now, CHANNEL_COMMAND, level, None, payload)
        )
        session = turn.control.id
    applied = hub.set_channel(rig_id, name, level, controller_session=session)
    agents, hosted = hosts
    if applied is None and rig_id in hosted and agents.set_channel(rig_id, name, level):
        applied = level
    return ChannelResult(rig_id, name, level, applied, None)
