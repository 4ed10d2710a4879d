"""Where a rig's runs go: its host's run service for a rig on a host, else this process's.

Routes and the lab ask one object, :class:`RunsByRig`, for every action on a
rig's current run (START, END, an input, a closed loop's commands, its state);
it alone knows which rigs live on a rig host (``agent = true``). Reading runs
back (lists, a run, its samples, exports) is the store's and the same for both:
:class:`~thermolab.lab.runs.service.RunService` serves it.
"""

from __future__ import annotations

from collections.abc import Callable, Container
from typing import Any, Protocol

from thermolab.lab.accounts.users import Principal
from thermolab.lab.runs.request import RunRequest
from thermolab.lab.runs.service import RunService
from thermolab.lab.runs.store import RunRecord
from thermolab.runner import LoopCommands

__all__ = ["RigRunService", "RunsByRig"]


class RigRunService(Protocol):
    """What runs a rig's experiments: this process's service, or a rig host's."""

    def start(self, rig_id: str, who: Principal, request: RunRequest) -> RunRecord:
        """START a run on the rig (the caller controls it)."""

    def stop(self, rig_id: str, who: Principal) -> RunRecord:
        """END the rig's current run."""

    def set_input(self, rig_id: str, u: float, *, control_session: int | None = None) -> int | None:
        """Hand an input to the rig's run; the run's id if one took it."""

    def command(
        self,
        rig_id: str,
        who: Principal,
        kind: str,
        payload: dict[str, Any],
        act: Callable[[LoopCommands], None],
    ) -> RunRecord:
        """Hand a closed-loop command to the rig's run."""

    def loop_state(self, rig_id: str) -> dict[str, Any] | None:
        """The rig's closed loop as it is now, if a closed-loop run is going."""

    def control_changed(self, rig_id: str, controller_session: int | None) -> None:
        """The rig's turn changed: a run of an ended turn ends."""

    def running(self, rig_id: str) -> int | None:
        """The id of the run going on the rig, if any."""


class RunsByRig:
    """Every action on a rig's current run, sent to the service where the rig lives.

    Parameters
    ----------
    here
        The runs of rigs this process drives.
    on_host
        The runs of rigs on a rig host.
    hosted
        The ids of the rigs on a host.
    """

    def __init__(self, here: RunService, on_host: RigRunService, hosted: Container[str]):
        self._here = here
        self._on_host = on_host
        self._hosted = hosted

    def of(self, rig_id: str) -> RigRunService:
        """The service that runs this rig's experiments."""
        return self._on_host if rig_id in self._hosted else self._here

    def start(self, rig_id: str, who: Principal, request: RunRequest) -> RunRecord:
        """START a run on the rig, here or on its host."""
        return self.of(rig_id).start(rig_id, who, request)

    def stop(self, rig_id: str, who: Principal) -> RunRecord:
        """END the rig's current run, here or on its host."""
        return self.of(rig_id).stop(rig_id, who)

    def set_input(self, rig_id: str, u: float, *, control_session: int | None = None) -> int | None:
        """Hand an input to the rig's run; the run's id if one took it."""
        return self.of(rig_id).set_input(rig_id, u, control_session=control_session)

    def command(
        self,
        rig_id: str,
        who: Principal,
        kind: str,
        payload: dict[str, Any],
        act: Callable[[LoopCommands], None],
    ) -> RunRecord:
        """Hand a closed-loop command to the rig's run, here or on its host."""
        return self.of(rig_id).command(rig_id, who, kind, payload, act)

    def loop_state(self, rig_id: str) -> dict[str, Any] | None:
        """The rig's closed loop as it is now, if a closed-loop run is going."""
        return self.of(rig_id).loop_state(rig_id)

    def control_changed(self, rig_id: str, controller_session: int | None) -> None:
        """The rig's turn changed: a run of an ended turn ends."""
        self.of(rig_id).control_changed(rig_id, controller_session)

    def running(self, rig_id: str) -> int | None:
        """The id of the run going on the rig, here or on its host, if any."""
        return self.of(rig_id).running(rig_id)
