"""The analytics' two tables as CSV files a spreadsheet opens safely.

Numbers are written as numbers (a dot for the decimals, seconds, ISO 8601
UTC instants), so the files read back the same in any locale. A text cell a
spreadsheet would take for a formula (starting with ``=``, ``+``, ``-``,
``@``, a tab or a carriage return: OWASP's "CSV injection") gets a leading
apostrophe; only names and titles are text here, and they come from people.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable
from datetime import datetime

from thermolab.ident.registry import METHOD_NAMES
from thermolab.lab.analytics.service import CourseAnalytics
from thermolab.lab.db.models import RunStatus

__all__ = ["rigs_csv", "safe_cell", "students_csv"]

_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
_RESULT_FIELDS = ("K", "tau", "theta", "trusted")


def safe_cell(value: object) -> str | int | float:
    """A CSV cell: numbers as they are, ``None`` empty, text defused if it could be a formula.

    Examples
    --------
    >>> safe_cell("=HYPERLINK(\\"http://x\\")")
    '\\'=HYPERLINK("http://x")'
    >>> safe_cell(-1.5), safe_cell(None), safe_cell(True)
    (-1.5, '', 'true')
    """
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return value
    if isinstance(value, datetime):
        return value.isoformat()
    text = str(value)
    return "'" + text if text.startswith(_FORMULA_START) else text


def students_csv(data: CourseAnalytics) -> str:
    """One line per student: time, runs by status, and each method's latest result."""
    used = {r.method for s in data.students for r in s.results}
    methods = [m for m in METHOD_NAMES if m in used] + sorted(used - set(METHOD_NAMES))
    header = [
        "username",
        "display_name",
        "control_seconds",
        "turns",
        "runs",
        *(f"runs_{status.value}" for status in RunStatus),
        "methods",
        *(f"{m}_{f}" for m in methods for f in ("runs", "run_id", *_RESULT_FIELDS)),
        "assignments_assigned",
        "assignments_submitted",
        "assignments_late",
        "assignments_marked",
        "assignments_mean_mark",
    ]
    rows: list[list[object]] = []
    for s in data.students:
        by_method = {r.method: r for r in s.results}
        cells: list[object] = [
            s.username,
            s.display_name,
            round(s.control_seconds, 3),
            s.turns,
            s.run_count,
            *(s.runs.get(status.value, 0) for status in RunStatus),
            " ".join(r.method for r in s.results),
        ]
        for m in methods:
            r = by_method.get(m)
            cells += [None] * 6 if r is None else [r.runs, r.run_id, r.K, r.tau, r.theta, r.trusted]
        a = s.assignments
        cells += (
            [None] * 5 if a is None else [a.assigned, a.submitted, a.late, a.marked, a.mean_mark]
        )
        rows.append(cells)
    return _write(header, rows)


def rigs_csv(data: CourseAnalytics) -> str:
    """One line per rig: use, queue waits, faults and hours powered (seconds)."""
    header = [
        "rig",
        "title",
        "control_seconds",
        "turns",
        "students",
        "runs",
        "failed_runs",
        "interlock_runs",
        "rig_faults",
        "waits",
        "wait_median_seconds",
        "wait_p90_seconds",
        "powered_seconds",
        "power_recorded_since",
    ]
    rows: list[list[object]] = [
        [
            r.rig,
            r.title,
            round(r.control_seconds, 3),
            r.turns,
            r.students,
            r.runs,
            r.failed_runs,
            r.interlock_runs,
            r.rig_faults,
            r.waits.count,
            r.waits.median,
            r.waits.p90,
            round(r.powered_seconds, 3),
            r.power_recorded_since,
        ]
        for r in data.rigs
    ]
    return _write(header, rows)


def _write(header: list[str], rows: Iterable[list[object]]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\r\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([safe_cell(cell) for cell in row])
    return out.getvalue()
