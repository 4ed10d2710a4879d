"""Assignments with automatic assessment (issue #10 item 4).

* :mod:`.marking` — the pure marking function and its result objects;
* :mod:`.identify` — a handed-in run identified again by the library;
* :mod:`.reference` — a rig's reference model (a twin's true parameters);
* :mod:`.grades` — grade rows and their formula-safe CSV;
* :mod:`.service` — assignments, hand-ins and grades on the database.
"""

from thermolab.lab.assignments.grades import GradeRow, grades_csv
from thermolab.lab.assignments.marking import Answers, Assessment, Tolerances, assess
from thermolab.lab.assignments.service import (
    AssignmentDraft,
    AssignmentInfo,
    AssignmentService,
    SubmissionInfo,
)

__all__ = [
    "Answers",
    "Assessment",
    "AssignmentDraft",
    "AssignmentInfo",
    "AssignmentService",
    "GradeRow",
    "SubmissionInfo",
    "Tolerances",
    "assess",
    "grades_csv",
]
