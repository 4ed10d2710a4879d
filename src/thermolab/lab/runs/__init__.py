"""Experiment runs on the lab's rigs.

* :mod:`.request` — :class:`RunRequest` and its one validation;
* :mod:`.operating_point` — the identifiers' ``offset`` (``auto``: the data decide);
* :mod:`.timing` — how well a run kept its sampling times (lateness, period spread);
* :mod:`.statistics` — the paper's figures, computed once at the end of a run;
* :mod:`.store` — samples, results and reading them back (and the CSV export);
* :mod:`.service` — :class:`RunService`: START, input, END, threads.
"""

from thermolab.jsonsafe import json_safe
from thermolab.lab.runs.operating_point import OperatingPoint, choose_operating_point
from thermolab.lab.runs.request import (
    MAX_DT,
    MAX_SAMPLES,
    MIN_DT,
    OFFSET_MODES,
    RunRequest,
    check_request,
)
from thermolab.lab.runs.service import RunService
from thermolab.lab.runs.statistics import CONVERGENCE_TOL, STATS_LAST, method_statistics
from thermolab.lab.runs.store import DatabaseRecorder, RunRecord, RunStore, samples_csv

__all__ = [
    "CONVERGENCE_TOL",
    "MAX_DT",
    "MAX_SAMPLES",
    "MIN_DT",
    "OFFSET_MODES",
    "STATS_LAST",
    "DatabaseRecorder",
    "OperatingPoint",
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
