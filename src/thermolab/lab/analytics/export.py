"""The analytics' two tables as CSV files a spreadsheet opens safely.

Numbers are written as numbers (a dot for the decimals, seconds, ISO 8601
UTC instants), so the files read back the same in any locale. A text cell a
spreadsheet would take for a formula (starting with ``=``, ``+``, ``-``,
``@``, a tab or a carriage return: OWASP's "CSV injection") gets a leading
apostrophe; only names and titles are text here, and they come from people.
Given a :class:`~thermolab.lab.spreadsheets.SheetDialect`, each table is
written in the spreadsheet form instead: headings in the language, the mean
mark as a percentage of the maximum (one decimal), local times.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Mapping
from datetime import datetime

from thermolab.ident.registry import METHOD_NAMES
from thermolab.lab.analytics.service import CourseAnalytics
from thermolab.lab.db.models import RunStatus
from thermolab.lab.spreadsheets import SheetDialect, machine_number

__all__ = ["rigs_csv", "safe_cell", "students_csv"]

_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
_RESULT_FIELDS = ("K", "tau", "theta", "trusted")
#: The spreadsheet form's headings of the students' table (English msgids; a
#: method's columns are built from the method's name, see ``_method_headings``).
_STUDENT_HEADINGS = {
    "username": "Login name",
    "display_name": "Name",
    "control_seconds": "Time in control (s)",
    "turns": "Turns",
    "runs": "Runs",
    **{f"runs_{status.value}": f"Runs {status.value}" for status in RunStatus},
    "methods": "Methods",
    "assignments_assigned": "Assignments set",
    "assignments_submitted": "Assignments handed in",
    "assignments_late": "Assignments late",
    "assignments_marked": "Assignments marked",
    "assignments_mean_mark": "Mean mark (% of the maximum)",
}
_RIG_HEADINGS = {
    "rig": "Rig",
    "title": "Title",
    "control_seconds": "Time in control (s)",
    "turns": "Turns",
    "students": "Students",
    "runs": "Runs",
    "failed_runs": "Failed runs",
    "interlock_runs": "Runs stopped by an interlock",
    "rig_faults": "Rig faults",
    "waits": "Waits",
    "wait_median_seconds": "Median wait (s)",
    "wait_p90_seconds": "90th percentile wait (s)",
    "powered_seconds": "Time powered (s)",
    "power_recorded_since": "Power recorded since",
}


def safe_cell(value: object) -> str | int:
    """A CSV cell: numbers as they are, ``None`` empty, text defused if it could be a formula.

    Examples
    --------
    >>> safe_cell("=HYPERLINK(\\"http://x\\")")
    '\\'=HYPERLINK("http://x")'
    >>> safe_cell(-1.5), safe_cell(None), safe_cell(True), safe_cell(250.12623300000004)
    ('-1.5', '', 'true', '250.126233')
    """
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return machine_number(value)  # no float noise (250.12623300000004)
    if isinstance(value, datetime):
        return value.isoformat()
    text = str(value)
    return "'" + text if text.startswith(_FORMULA_START) else text


def students_csv(data: CourseAnalytics, dialect: SheetDialect | None = None) -> str:
    """One line per student: time, runs by status, and each method's latest result.

    The machine form, or with ``dialect`` the spreadsheet form.
    """
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
        if a is None:
            cells += [None] * 5
        else:
            # The page shows the mean to one decimal; the machine form keeps every digit.
            mean = a.mean_mark if dialect is None or a.mean_mark is None else round(a.mean_mark, 1)
            cells += [a.assigned, a.submitted, a.late, a.marked, mean]
        rows.append(cells)
    if dialect is not None:
        built = _method_headings(methods, dialect)
        return dialect.document([_heading(h, dialect, built) for h in header], rows)
    return _write(header, rows)


def rigs_csv(data: CourseAnalytics, dialect: SheetDialect | None = None) -> str:
    """One line per rig: use, queue waits, faults and hours powered (seconds).

    The machine form, or with ``dialect`` the spreadsheet form.
    """
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
    if dialect is not None:
        return dialect.document([_heading(h, dialect) for h in header], rows)
    return _write(header, rows)


def _method_headings(methods: list[str], dialect: SheetDialect) -> dict[str, str]:
    # The paper's symbols are the same in every language; only the words are translated.
    out: dict[str, str] = {}
    for m in methods:
        name = m.upper()
        out |= {
            f"{m}_runs": dialect.word("{method}: runs", method=name),
            f"{m}_run_id": dialect.word("{method}: latest run", method=name),
            f"{m}_K": f"{name}: Ks",
            f"{m}_tau": f"{name}: Ts",
            f"{m}_theta": f"{name}: θ",
            f"{m}_trusted": dialect.word("{method}: trusted", method=name),
        }
    return out


def _heading(column: str, dialect: SheetDialect, built: Mapping[str, str] | None = None) -> str:
    if built and column in built:
        return built[column]
    word = {**_STUDENT_HEADINGS, **_RIG_HEADINGS}[column]
    return dialect.timed(word) if column == "power_recorded_since" else dialect.word(word)


def _write(header: list[str], rows: Iterable[list[object]]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\r\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([safe_cell(cell) for cell in row])
    return out.getvalue()
