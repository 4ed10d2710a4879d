"""Experiment runs on the lab's rigs.

* :mod:`.request` — :class:`RunRequest`, its one validation and the identifiers'
  ``offset`` (``auto``: the data decide), together as :func:`plan_run`; the run's
  length against the rig's limit;
* :mod:`.timing` — how well a run kept its sampling times (lateness, period spread);
* :mod:`.statistics` — the paper's figures, computed once at the end of a run;
* :mod:`.store` — a run's row and channel specs, its samples as they come
  (:class:`DatabaseRecorder`), its results, reading the run back;
* :mod:`.export` — the samples read back by channel, the CSV and JSON exports;
* :mod:`.active` — :class:`~.active.ActiveRun`: a run going on a rig, read as it is now;
* :mod:`.commands` — what is sent to a running run: END, an input, a closed loop's
  commands (mode, set point, gains, fan) and its state;
* :mod:`.channels` — a rig's further input (a kit's heater 2), in a run or on the
  idle rig;
* :mod:`.ending` — what is stored when a run ends: status, results with their
  statistics, timing, the controller as it ended (and storing it);
* :mod:`.reading` — reading runs back for the routes (:class:`RunService`'s base);
* :mod:`.service` — :class:`RunService`: START, the hand-over wait, the run's
  thread and its end, a run as it is now.
"""

from thermolab.jsonsafe import json_safe
from thermolab.lab.runs.export import RunExport, samples_csv
from thermolab.lab.runs.recorder import DatabaseRecorder
from thermolab.lab.runs.request import (
    MAX_DT,
    MAX_SAMPLES,
    MIN_DT,
    OFFSET_MODES,
    OperatingPoint,
    RunRequest,
    check_request,
    choose_operating_point,
)
from thermolab.lab.runs.service import RunService
from thermolab.lab.runs.statistics import CONVERGENCE_TOL, STATS_LAST, method_statistics
from thermolab.lab.runs.store import RunRecord, RunStore

__all__ = [
    "CONVERGENCE_TOL",
    "MAX_DT",
    "MAX_SAMPLES",
    "MIN_DT",
    "OFFSET_MODES",
    "STATS_LAST",
    "DatabaseRecorder",
    "OperatingPoint",
    "RunExport",
    "RunRecord",
    "RunRequest",
    "RunService",
    "RunStore",
    "check_request",
    "choose_operating_point",
    "json_safe",
    "method_statistics",
    "samples_csv",
]
