"""A run going on a rig: what the lab holds of it from START until its end is stored.

:class:`~thermolab.lab.runs.service.RunService` keeps one per rig while the
run goes; what is sent to the run (:mod:`.commands`) acts on its
experiment and the end of the run (:mod:`.ending`) reads its identifiers and
who stopped it.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

from thermolab.ident.online import OnlineIdentifier
from thermolab.jsonsafe import json_safe
from thermolab.runner import Experiment

__all__ = ["ActiveRun"]


@dataclass
class ActiveRun:
    """A run that has started and whose end is not stored yet.

    Attributes
    ----------
    run_id : int
    rig_id : str
    control_session : int
        The turn at the controls the run belongs to (it ends with that turn).
    experiment : Experiment
        The sampling, on the rig's driver, in a thread of its own.
    identifiers : dict
        The online identifiers by method name (their settings are stored with the results).
    thread : threading.Thread or None
        The thread that waits for the run's end and stores it.
    stopped_by : str or None
        Who or what ENDed the run (a user name, "the server stopped"...).
    """

    run_id: int
    rig_id: str
    control_session: int
    experiment: Experiment
    identifiers: dict[str, OnlineIdentifier]
    thread: threading.Thread | None = None
    stopped_by: str | None = None

    def now(self) -> tuple[dict[str, Any], int, dict[str, Any] | None]:
        """The run as it is now: each method's latest result, the samples taken, the
        controller (``ControlLoop.to_dict``; ``None`` without one), all JSON-ready."""
        loop = self.experiment.controller
        control = None if loop is None else json_safe(loop.to_dict())
        snapshot = self.experiment.snapshot()
        results = {name: json_safe(method.to_dict()) for name, method in snapshot.methods.items()}
        return results, snapshot.samples, control
