"""Class analytics: what a course's students did, and how its rigs were used.

:mod:`.sql` holds the portable SQL pieces (seconds between two instants,
clipping to a window, percentiles) that SQLite and PostgreSQL spell
differently; :mod:`.students` and :mod:`.rigs` the set-based queries of each
table; :mod:`.service` puts them together for one course and a time window;
:mod:`.export` writes both tables as CSV; :mod:`.assignments` is where the
assignment state of each student comes from.
"""

from thermolab.lab.analytics.assignments import (
    AssignmentSource,
    AssignmentSummary,
    assignment_state,
)
from thermolab.lab.analytics.service import (
    AnalyticsService,
    CourseAnalytics,
    RigFigures,
    StudentFigures,
    Window,
)

__all__ = [
    "AnalyticsService",
    "AssignmentSource",
    "AssignmentSummary",
    "CourseAnalytics",
    "RigFigures",
    "StudentFigures",
    "Window",
    "assignment_state",
]
