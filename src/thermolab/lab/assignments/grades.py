"""Grades as rows and as a CSV file a spreadsheet opens safely.

:class:`GradeRow` is what other parts of the lab (LTI grade passback,
analytics) read: one row per (course, assignment, student), the student's
current hand-in's mark or none. :func:`grades_csv` writes them; a text cell
that a spreadsheet would run as a formula (starting with ``= + - @``, a tab or
a carriage return) is prefixed with an apostrophe (OWASP's advice for CSV
injection), so a display name like ``=HYPERLINK(...)`` stays text. Given a
:class:`~thermolab.lab.spreadsheets.SheetDialect`, it writes the spreadsheet
form instead: headings and states in the language, marks as the page shows
them, local times.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime

from thermolab.lab.spreadsheets import SheetDialect, machine_number

__all__ = ["GRADE_COLUMNS", "GradeRow", "grades_csv", "safe_cell"]

#: The CSV's columns, in order.
GRADE_COLUMNS: tuple[str, ...] = (
    "course",
    "assignment_id",
    "assignment",
    "student",
    "display_name",
    "state",
    "mark",
    "max",
    "late",
    "submitted_at",
    "marked_at",
    "run_id",
    "answer_K",
    "answer_tau",
    "answer_theta",
    "conclusion",
    "automatic_mark",
    "comment",
)

_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
#: The spreadsheet form's headings (an English msgid of ``SHEET_WORDS`` per column;
#: the instants' columns also name the time zone).
_HEADINGS = dict(
    zip(
        GRADE_COLUMNS,
        (
            *("Course", "Assignment no.", "Assignment", "Login name", "Name", "State", "Mark"),
            *("Out of", "Late", "Handed in at", "Marked at", "Run", "Answer Ks", "Answer Ts"),
            *("Answer θ", "Conclusion", "Automatic mark", "Teacher's comment"),
        ),
        strict=True,
    )
)
_TIMED = frozenset({"submitted_at", "marked_at"})
#: A row's state in words (the words the assignments page uses).
_STATES = {"marked": "marked", "review": "to review", "missing": "not handed in"}


@dataclass(frozen=True, slots=True)
class GradeRow:
    """A student's standing on one assignment.

    Attributes
    ----------
    course : str
        The course's name.
    assignment_id : int
    assignment : str
        The assignment's title.
    student : str
        The login name.
    display_name : str or None
    state : {"marked", "review", "missing"}
        ``review``: handed in, no automatic mark (the identification is not
        trustworthy); ``missing``: nothing handed in.
    mark : float or None
        The final mark: a teacher's override, else the automatic mark;
        ``None`` unless ``state`` is ``marked``.
    max : float
    marked_at, submitted_at : datetime or None
    late : bool
    run_id : int or None
    answer_K, answer_tau, answer_theta : float or None
        The student's answers (``None`` when missing).
    conclusion : str
        The student's conclusion.
    automatic_mark : float or None
        The lab's own mark of the hand-in (equal to ``mark`` unless a teacher
        overrode it; ``None`` when missing or to review).
    comment : str
        The teacher's comment on an overridden mark ("" when not overridden).
    """

    course: str
    assignment_id: int
    assignment: str
    student: str
    display_name: str | None
    state: str
    mark: float | None
    max: float
    marked_at: datetime | None
    submitted_at: datetime | None
    late: bool
    run_id: int | None
    answer_K: float | None = None  # noqa: N815 - the paper's symbol
    answer_tau: float | None = None
    answer_theta: float | None = None
    conclusion: str = ""
    automatic_mark: float | None = None
    comment: str = ""


def safe_cell(value: object) -> str:
    """A value as CSV text a spreadsheet will not run as a formula.

    Examples
    --------
    >>> safe_cell("=1+1"), safe_cell("Ana"), safe_cell(7.5), safe_cell(None)
    ("'=1+1", 'Ana', '7.5', '')
    """
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, datetime):
        return value.isoformat()
    if isinstance(value, int | float):
        return machine_number(value)  # no float noise (250.12623300000004)
    text = str(value)
    return "'" + text if text.startswith(_FORMULA_START) else text


def grades_csv(rows: Iterable[GradeRow], dialect: SheetDialect | None = None) -> str:
    r"""The grades as CSV text (a header, then one line per row).

    Parameters
    ----------
    rows : iterable of GradeRow
    dialect : SheetDialect, optional
        The spreadsheet form to write; the machine form (below) without it.

    Examples
    --------
    >>> from datetime import UTC, datetime
    >>> at = datetime(2026, 11, 24, tzinfo=UTC)
    >>> row = GradeRow("c1", 1, "Step", "ana", "=cmd", "marked", 7.5, 10.0, at, at, False, 3)
    >>> print(grades_csv([row]).splitlines()[1])
    c1,1,Step,ana,'=cmd,marked,7.5,10.0,no,2026-11-24T00:00:00+00:00,2026-11-24T00:00:00+00:00,3,,,,,,
    """
    if dialect is not None:
        return _grades_sheet(rows, dialect)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(GRADE_COLUMNS)
    for row in rows:
        writer.writerow(
            [
                safe_cell(row.course),
                safe_cell(row.assignment_id),
                safe_cell(row.assignment),
                safe_cell(row.student),
                safe_cell(row.display_name),
                safe_cell(row.state),
                safe_cell(row.mark),
                safe_cell(row.max),
                safe_cell(row.late),
                safe_cell(row.submitted_at),
                safe_cell(row.marked_at),
                safe_cell(row.run_id),
                safe_cell(row.answer_K),
                safe_cell(row.answer_tau),
                safe_cell(row.answer_theta),
                safe_cell(row.conclusion),
                safe_cell(row.automatic_mark),
                safe_cell(row.comment),
            ]
        )
    return out.getvalue()


def _grades_sheet(rows: Iterable[GradeRow], dialect: SheetDialect) -> str:
    header = [
        dialect.timed(_HEADINGS[c]) if c in _TIMED else dialect.word(_HEADINGS[c])
        for c in GRADE_COLUMNS
    ]
    state = {code: dialect.word(word) for code, word in _STATES.items()}
    return dialect.document(
        header,
        (
            [
                *(row.course, row.assignment_id, row.assignment, row.student, row.display_name),
                state.get(row.state, row.state),
                *(row.mark, row.max, row.late, row.submitted_at, row.marked_at, row.run_id),
                *(row.answer_K, row.answer_tau, row.answer_theta, row.conclusion),
                *(row.automatic_mark, row.comment),
            ]
            for row in rows
        ),
    )
