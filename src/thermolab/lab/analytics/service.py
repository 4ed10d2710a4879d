"""A course's analytics over a time window: one row per student, one per rig.

:class:`AnalyticsService` reads everything in one read transaction with a
handful of grouped queries (:mod:`.students`, :mod:`.rigs`), whatever the
size of the class; no sample is read.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timedelta

from sqlalchemy import Select, select
from sqlalchemy.orm import Session

from thermolab.errors import InvalidParameterError, NotFoundError
from thermolab.lab.analytics import rigs as rig_queries
from thermolab.lab.analytics import students as student_queries
from thermolab.lab.analytics.assignments import (
    AssignmentSource,
    AssignmentSummary,
    no_assignments,
)
from thermolab.lab.analytics.rigs import Waits
from thermolab.lab.analytics.students import LatestResult
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import Course, CourseMember, CourseRig, Role, RunStatus, User

__all__ = [
    "MAX_WINDOW",
    "AnalyticsService",
    "CourseAnalytics",
    "RigFigures",
    "StudentFigures",
    "Window",
]

#: The longest window asked for (ten years: a course's whole life, not an arbitrary span).
MAX_WINDOW = timedelta(days=3653)


@dataclass(frozen=True, slots=True)
class Window:
    """The instants ``[start, end)`` the figures cover (aware UTC)."""

    start: datetime
    end: datetime


@dataclass(frozen=True, slots=True)
class StudentFigures:
    """One student of a course within the window."""

    username: str
    display_name: str | None
    control_seconds: float
    turns: int
    runs: dict[str, int]
    results: tuple[LatestResult, ...]
    assignments: AssignmentSummary | None

    @property
    def run_count(self) -> int:
        """Runs started in the window, however they ended."""
        return sum(self.runs.values())


@dataclass(frozen=True, slots=True)
class RigFigures:
    """One rig within the window (use and waits: the course's students)."""

    rig: str
    title: str
    control_seconds: float
    turns: int
    students: int
    runs: int
    failed_runs: int
    interlock_runs: int
    rig_faults: int
    waits: Waits
    powered_seconds: float
    power_recorded_since: datetime | None


@dataclass(frozen=True, slots=True)
class CourseAnalytics:
    """A course's two tables for a window, and when they were computed."""

    course: str
    title: str
    window: Window
    computed_at: datetime
    students: tuple[StudentFigures, ...]
    rigs: tuple[RigFigures, ...] = field(default=())


class AnalyticsService:
    """Compute a course's analytics.

    Parameters
    ----------
    db : Database
    clock : LabClock
    config : LabConfig
        The configured rigs (their titles, and every rig for a course that lists none).
    assignments : AssignmentSource, optional
        Each student's assignment state (:mod:`.assignments`); none by default.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        config: LabConfig,
        *,
        assignments: AssignmentSource = no_assignments,
    ) -> None:
        self._db = db
        self._clock = clock
        self._config = config
        self._assignments = assignments

    def course(
        self, name: str, start: datetime | None = None, end: datetime | None = None
    ) -> CourseAnalytics:
        """The analytics of course ``name`` over ``[start, end)``.

        ``start`` defaults to the course's creation, ``end`` to now.

        Raises
        ------
        NotFoundError
            For an unknown course.
        InvalidParameterError
            For a window that is empty, reversed or longer than :data:`MAX_WINDOW`.
        """
        now = self._clock.now()
        with self._db.read() as session:
            course = session.scalars(
                select(Course).where(Course.name == name.strip().lower())
            ).one_or_none()
            if course is None:
                raise NotFoundError(f"no course called {name!r}")
            window = _window(start or course.created_at, end or now)
            students = select(CourseMember.user_id).where(
                CourseMember.course_id == course.id, CourseMember.role == Role.STUDENT.value
            )
            return CourseAnalytics(
                course=course.name,
                title=course.title,
                window=window,
                computed_at=now,
                students=self._students(session, course.id, students, window, now),
                rigs=self._rigs(session, course.id, students, window, now),
            )

    def _students(
        self,
        session: Session,
        course_id: int,
        students: Select[int],
        window: Window,
        now: datetime,
    ) -> tuple[StudentFigures, ...]:
        people = session.execute(
            select(User.id, User.username, User.display_name)
            .where(User.id.in_(students))
            .order_by(User.username)
        ).all()
        start, end = window.start, window.end
        control = student_queries.control_time(session, students, start, end, now)
        runs = student_queries.run_counts(session, students, start, end)
        results = student_queries.latest_results(session, students, start, end)
        marks = self._assignments(session, course_id, [p.id for p in people], start, end)
        return tuple(
            StudentFigures(
                username=username,
                display_name=display,
                control_seconds=control.get(user_id, (0, 0.0))[1],
                turns=control.get(user_id, (0, 0.0))[0],
                runs={s.value: runs.get(user_id, {}).get(s.value, 0) for s in _STATUSES},
                results=tuple(results.get(user_id, ())),
                assignments=marks.get(user_id),
            )
            for user_id, username, display in people
        )

    def _rigs(
        self,
        session: Session,
        course_id: int,
        students: Select[int],
        window: Window,
        now: datetime,
    ) -> tuple[RigFigures, ...]:
        listed = set(
            session.scalars(select(CourseRig.rig_id).where(CourseRig.course_id == course_id))
        )
        configured = [cfg for cfg in self._config.rigs if not listed or cfg.id in listed]
        start, end = window.start, window.end
        use = rig_queries.rig_use(session, students, start, end, now)
        waits = rig_queries.queue_waits(session, students, start, end)
        faults = rig_queries.faults(session, start, end)
        power = rig_queries.powered(session, start, end, now)
        out = []
        for cfg in configured:
            u = use.get(cfg.id, rig_queries.RigUse())
            on, since = power.get(cfg.id, (0.0, None))
            out.append(
                RigFigures(
                    rig=cfg.id,
                    title=cfg.title,
                    control_seconds=u.seconds,
                    turns=u.turns,
                    students=u.students,
                    runs=u.runs,
                    failed_runs=u.failed_runs,
                    interlock_runs=u.interlock_runs,
                    rig_faults=faults.get(cfg.id, 0),
                    waits=waits.get(cfg.id, Waits()),
                    powered_seconds=on,
                    power_recorded_since=since,
                )
            )
        return tuple(out)


#: The statuses a run is counted under (a run still going counts as running).
_STATUSES = tuple(RunStatus)


def _window(start: datetime, end: datetime) -> Window:
    if start.tzinfo is None or end.tzinfo is None:
        raise InvalidParameterError("the window's instants need a time zone (or 'Z' for UTC)")
    if end <= start:
        raise InvalidParameterError(
            f"the window is empty: 'to' ({end.isoformat()}) must be after 'from' "
            f"({start.isoformat()})"
        )
    if end - start > MAX_WINDOW:
        raise InvalidParameterError(
            f"the window is longer than {MAX_WINDOW.days} days; choose a shorter one"
        )
    return Window(start, end)
