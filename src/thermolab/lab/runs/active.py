"""A run going on a rig: what the lab holds of it from START until its end is stored.

:class:`~thermolab.lab.runs.service.RunService` keeps one per rig while the
run goes; the closed-loop commands (:mod:`.loop_commands`) act on its
experiment and the end of the run (:mod:`.ending`) reads its identifiers and
who stopped it.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from thermolab.ident.online import OnlineIdentifier
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
