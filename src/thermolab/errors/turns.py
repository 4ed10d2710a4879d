"""Why the lab refuses an action at a rig: turns at the controls, runs, the rig's availability."""

from __future__ import annotations

from thermolab.errors.base import ConflictError

__all__ = [
    "FaultNotClearedError",
    "HostOfflineError",
    "LabStartingError",
    "NobodyControlsError",
    "NotControllerError",
    "PreviousRunEndingError",
    "RigOutOfServiceError",
    "RunInProgressError",
    "TurnEndedError",
    "TurnExtensionRefusedError",
]


class TurnEndedError(ConflictError):
    """The turn at the controls ended while the request was being decided (it lost the race)."""


class RunInProgressError(ConflictError):
    """A run of the caller's own turn is already going on the rig (END it first)."""


class PreviousRunEndingError(ConflictError):
    """Right after a hand-over, the previous turn's run is still ENDing and storing its data."""


class TurnExtensionRefusedError(ConflictError):
    """A controller may not extend the turn now (someone waits, too early, or no room left)."""


# Why a rig takes no turn now: each its own stable code, so a page says which.
class RigOutOfServiceError(ConflictError):
    """A rig a teacher took out of service."""


class FaultNotClearedError(ConflictError):
    """A rig whose fault a teacher has not cleared yet."""


class LabStartingError(ConflictError):
    """A rig asked for before the lab has read its state at start-up."""


class HostOfflineError(ConflictError):
    """A rig whose host (the computer its kit hangs on) is not connected."""


class NotControllerError(ConflictError):
    """A controller's action by someone who does not control the rig."""


class NobodyControlsError(ConflictError):
    """A teacher's action on the controller of a rig nobody controls."""
