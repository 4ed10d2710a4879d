"""Class analytics (teachers): a course's students and rigs over a time window, JSON or CSV.

``from`` and ``to`` are ISO 8601 instants (``2026-03-01T00:00:00Z``; a date
alone is midnight UTC; an instant without a zone is UTC); by default the
window runs from the course's creation to now.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated

from fastapi import APIRouter, Query
from fastapi.responses import Response
from pydantic import Field

from thermolab.errors import InvalidParameterError
from thermolab.lab.accounts.policy import Action
from thermolab.lab.analytics import CourseAnalytics, RigFigures, StudentFigures
from thermolab.lab.analytics.export import rigs_csv, students_csv
from thermolab.lab.http.bodies import Out
from thermolab.lab.http.deps import AUTHENTICATED, LabDep, SheetDep, UserDep, documented_errors
from thermolab.lab.http.routers.courses import CourseName

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)

_INSTANT = r"^\d{4}-\d{2}-\d{2}([T ]\d{2}:\d{2}(:\d{2}(\.\d{1,6})?)?(Z|[+-]\d{2}:?\d{2})?)?$"
From = Annotated[
    str | None,
    Query(
        alias="from",
        min_length=10,
        max_length=32,
        pattern=_INSTANT,
        description="start of the window (ISO 8601; default: the course's creation)",
    ),
]
To = Annotated[
    str | None,
    Query(
        alias="to",
        min_length=10,
        max_length=32,
        pattern=_INSTANT,
        description="end of the window, excluded (ISO 8601; default: now)",
    ),
]


class ResultOut(Out):
    """A method's result in the student's newest run that used it."""

    method: str
    runs: int
    run_id: int
    at: datetime
    K: Annotated[float | None, Field(alias="K")]  # the paper's symbol, not camelCased to "k"
    tau: float | None
    theta: float | None
    trusted: bool


class AssignmentsOut(Out):
    """A student's assignments (from the assignments' source)."""

    assigned: int
    submitted: int
    late: int
    marked: int
    mean_mark: float | None


class StudentOut(Out):
    """One student: time at the controls (s), turns, runs by status, methods, results."""

    username: str
    display_name: str | None
    control_seconds: float
    turns: int
    runs: int
    runs_by_status: dict[str, int]
    results: list[ResultOut]
    assignments: AssignmentsOut | None

    @classmethod
    def of(cls, s: StudentFigures) -> StudentOut:
        """Build from :class:`~thermolab.lab.analytics.StudentFigures`."""
        a = s.assignments
        return cls(
            username=s.username,
            display_name=s.display_name,
            control_seconds=s.control_seconds,
            turns=s.turns,
            runs=s.run_count,
            runs_by_status=s.runs,
            results=[
                ResultOut(
                    method=r.method,
                    runs=r.runs,
                    run_id=r.run_id,
                    at=r.at,
                    K=r.K,
                    tau=r.tau,
                    theta=r.theta,
                    trusted=r.trusted,
                )
                for r in s.results
            ],
            assignments=None
            if a is None
            else AssignmentsOut(
                assigned=a.assigned,
                submitted=a.submitted,
                late=a.late,
                marked=a.marked,
                mean_mark=a.mean_mark,
            ),
        )


class WaitsOut(Out):
    """Waits from joining the queue to control (s): how many, median, 90th percentile."""

    count: int
    median: float | None
    p90: float | None


class RigOut(Out):
    """One rig: use by the course's students, their waits, faults, time powered (s)."""

    rig: str
    title: str
    control_seconds: float
    turns: int
    students: int
    runs: int
    failed_runs: int
    interlock_runs: int
    rig_faults: int
    waits: WaitsOut
    powered_seconds: float
    power_recorded_since: datetime | None

    @classmethod
    def of(cls, r: RigFigures) -> RigOut:
        """Build from :class:`~thermolab.lab.analytics.RigFigures`."""
        return cls(
            rig=r.rig,
            title=r.title,
            control_seconds=r.control_seconds,
            turns=r.turns,
            students=r.students,
            runs=r.runs,
            failed_runs=r.failed_runs,
            interlock_runs=r.interlock_runs,
            rig_faults=r.rig_faults,
            waits=WaitsOut(count=r.waits.count, median=r.waits.median, p90=r.waits.p90),
            powered_seconds=r.powered_seconds,
            power_recorded_since=r.power_recorded_since,
        )


class AnalyticsOut(Out):
    """A course's analytics for the window ``[from, to)``."""

    course: str
    title: str
    window_from: datetime
    window_to: datetime
    computed_at: datetime
    students: list[StudentOut]
    rigs: list[RigOut]

    @classmethod
    def of(cls, data: CourseAnalytics) -> AnalyticsOut:
        """Build from :class:`~thermolab.lab.analytics.CourseAnalytics`."""
        return cls(
            course=data.course,
            title=data.title,
            window_from=data.window.start,
            window_to=data.window.end,
            computed_at=data.computed_at,
            students=[StudentOut.of(s) for s in data.students],
            rigs=[RigOut.of(r) for r in data.rigs],
        )


def parse_instant(text: str | None, name: str) -> datetime | None:
    """An ISO 8601 query value as an aware UTC instant (no zone: UTC).

    Raises
    ------
    InvalidParameterError
        For a date or time that does not exist (``2026-02-30``).
    """
    if text is None:
        return None
    try:
        value = datetime.fromisoformat(text)
    except ValueError:
        raise InvalidParameterError(f"{name!r} is not a valid date or instant: {text!r}") from None
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


def _analytics(course: str, start: str | None, end: str | None, lab: LabDep) -> CourseAnalytics:
    return lab.analytics.course(course, parse_instant(start, "from"), parse_instant(end, "to"))


@router.get(
    "/courses/{course}/analytics",
    response_model=AnalyticsOut,
    tags=["courses"],
    summary="A course's analytics",
    responses=documented_errors(403, 404, 422),
)
def course_analytics(
    course: CourseName, who: UserDep, lab: LabDep, start: From = None, end: To = None
) -> AnalyticsOut:
    """Per student and per rig figures over a window (teachers only)."""
    lab.authorize.require_course(who, Action.COURSE_ANALYTICS, course)
    return AnalyticsOut.of(_analytics(course, start, end, lab))


_CSV = {200: {"content": {"text/csv": {}}}, **documented_errors(403, 404, 422)}


@router.get(
    "/courses/{course}/analytics/students.csv",
    tags=["courses"],
    summary="A course's students' figures as CSV",
    response_class=Response,
    responses=_CSV,
)
def students_table(
    course: CourseName,
    who: UserDep,
    lab: LabDep,
    sheet: SheetDep,
    start: From = None,
    end: To = None,
) -> Response:
    """The students' table, one line per student (teachers only; formula-safe cells).

    ``?dialect=pt-BR`` (or ``en``, ``es``) and ``tz``: the spreadsheet form.
    """
    lab.authorize.require_course(who, Action.COURSE_ANALYTICS, course)
    data = _analytics(course, start, end, lab)
    return _csv(students_csv(data, sheet), f"{data.course}-students.csv")


@router.get(
    "/courses/{course}/analytics/rigs.csv",
    tags=["courses"],
    summary="A course's rigs' figures as CSV",
    response_class=Response,
    responses=_CSV,
)
def rigs_table(
    course: CourseName,
    who: UserDep,
    lab: LabDep,
    sheet: SheetDep,
    start: From = None,
    end: To = None,
) -> Response:
    """The rigs' table, one line per rig (teachers only; formula-safe cells).

    ``?dialect=pt-BR`` (or ``en``, ``es``) and ``tz``: the spreadsheet form.
    """
    lab.authorize.require_course(who, Action.COURSE_ANALYTICS, course)
    data = _analytics(course, start, end, lab)
    return _csv(rigs_csv(data, sheet), f"{data.course}-rigs.csv")


def _csv(text: str, filename: str) -> Response:
    return Response(
        text,
        media_type="text/csv; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )
