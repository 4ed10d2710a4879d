"""What is sent to a run while it goes: END, an input, a closed loop's commands.

What START asks of a closed loop's controller and its one check are
:mod:`.control`; here are the commands the controller sends afterwards
(``PUT .../runs/current/mode``, ``setpoint``, ``gains``, ``fan``; a further
input's level, :mod:`thermolab.lab.runs.channels`) and the
loop's state read back. Each closed-loop command is checked by the run's
:class:`~thermolab.runner.Experiment` before anything changes, applied from
the run's next sample on, and recorded in ``commands``. Each function takes
the rig's :class:`~.active.ActiveRun` (``None``: no run is going).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from thermolab.errors import AccessDeniedError, NoRunError, NotClosedLoopError
from thermolab.jsonsafe import json_safe
from thermolab.lab.access import AccessService
from thermolab.lab.accounts.users import Principal
from thermolab.lab.runs.active import ActiveRun
from thermolab.lab.runs.store import run_command
from thermolab.runner import LoopCommands

__all__ = [
    "CHANNEL_COMMAND",
    "OPEN_LOOP_COMMANDS",
    "GoingRun",
    "end_run",
    "hand_input",
    "loop_state",
    "send_command",
]

#: The command that sets a rig's further input (a kit's heater 2) in a run.
CHANNEL_COMMAND = "channel"
#: Commands an open-loop run takes too: the inputs beside ``u`` (the fan, a further input).
OPEN_LOOP_COMMANDS = frozenset({"fan", CHANNEL_COMMAND})


class GoingRun(Protocol):
    """What :func:`send_command` needs of a run: an :class:`~.active.ActiveRun`, or a rig
    host's (:mod:`thermolab.lab.agents.runs`), whose ``experiment`` forwards the commands."""

    @property
    def run_id(self) -> int:
        """The run's id."""
        ...

    @property
    def control_session(self) -> int:
        """The turn the run belongs to."""
        ...

    @property
    def experiment(self) -> LoopCommands:
        """What the commands act on."""
        ...


def end_run(access: AccessService, active: ActiveRun | None, rig_id: str, who: Principal) -> int:
    """END the run ``active`` (its controller, or a teacher); return its id at once.

    Raises
    ------
    AccessDeniedError
        If ``who`` neither controls the rig nor is a teacher.
    ConflictError
        If no run is going on the rig.
    """
    if active is None:
        raise NoRunError(f"no run is going on rig {rig_id!r}")
    if not who.is_teacher:
        snap = access.snapshot(rig_id)
        if snap.controller is None or snap.controller.user_id != who.user_id:
            raise AccessDeniedError(f"only the controller of rig {rig_id!r} may END its run")
    active.stopped_by = who.username
    active.experiment.end()
    return active.run_id


def hand_input(active: ActiveRun | None, u: float, control_session: int | None) -> int | None:
    """Hand a new input to the run ``active``; return its id (``None``: no run took it).

    With ``control_session``, only a run of that turn takes the input (an
    input of the next controller never lands in the previous one's run).
    """
    if active is None:
        return None
    if control_session is not None and active.control_session != control_session:
        return None
    active.experiment.set_input(u)
    return active.run_id


def send_command(
    access: AccessService,
    active: GoingRun | None,
    rig_id: str,
    who: Principal,
    kind: str,
    payload: dict[str, Any],
    act: Callable[[LoopCommands], None],
) -> int:
    """Hand a closed-loop command to the rig's run ``active``; return the run's id.

    Only the controller, in the turn the run belongs to, may; ``act`` is
    applied to the run's :class:`~thermolab.runner.Experiment` (which checks
    the values and raises before changing anything; a rig host's run: its
    :class:`~thermolab.lab.agents.loop.RemoteLoop`, which checks them alike and
    forwards them), then the command is
    recorded (``commands``, kind ``kind``, ``payload``), in the same
    transaction of the rig. The run applies it from its next sample on, after
    the interlocks, as any input.

    Raises
    ------
    AccessDeniedError
        ``who`` does not control the rig (checked first, run or not), or the run
        belongs to an earlier turn.
    NoRunError
        No run is going on the rig (``active`` is ``None``).
    NotClosedLoopError
        The run has no controller (and the command is not in :data:`OPEN_LOOP_COMMANDS`).
    """
    # Who may act is asked first: someone who does not control the rig hears 403
    # whether or not a run is going (the run's state is not theirs to learn).
    with access.controlled(rig_id, who, f"send {kind} to its run") as turn:
        if active is None:
            raise NoRunError(f"no run is going on rig {rig_id!r}: start a closed-loop run first")
        if active.experiment.controller is None and kind not in OPEN_LOOP_COMMANDS:
            raise NotClosedLoopError(
                f"run {active.run_id} was started without a controller; start a run with "
                "control (manual or auto) to switch, change the set point or the gains"
            )
        if turn.control.id != active.control_session:
            raise AccessDeniedError(
                f"run {active.run_id} belongs to an earlier turn at rig {rig_id!r}"
            )
        act(active.experiment)
        turn.session.add(
            run_command(rig_id, turn.control, who, turn.now, kind, None, active.run_id, payload)
        )
    return active.run_id


def loop_state(active: GoingRun | None) -> dict[str, Any] | None:
    """The control loop of the run ``active`` now (``ControlLoop.to_dict``), or ``None``."""
    if active is None or active.experiment.controller is None:
        return None
    state: dict[str, Any] = json_safe(active.experiment.controller.to_dict())
    return {**state, "run": active.run_id}
