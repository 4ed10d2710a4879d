"""Assignments with automatic assessment (issue #10 item 4).

* :mod:`.marking` — the pure marking function and its result objects;
* :mod:`.identify` — a handed-in run identified again by the library;
* :mod:`.reference` — a rig's reference model (a twin's true parameters);
* :mod:`.grades` — grade rows and their formula-safe CSV;
* :mod:`.rows` — the information objects and shared lookups;
* :mod:`.overrides`, :mod:`.extensions`, :mod:`.groups` — a teacher's tools:
  a mark overridden with a comment, one student's later deadline, lab groups;
* :mod:`.standing` — each student's standing on an assignment (the teachers' table);
* :mod:`.service` — assignments, hand-ins and grades on the database.
"""

from thermolab.lab.assignments.extensions import ExtensionInfo
from thermolab.lab.assignments.grades import GradeRow, grades_csv
from thermolab.lab.assignments.marking import Answers, Assessment, Tolerances, assess
from thermolab.lab.assignments.rows import AssignmentInfo, GroupInfo, OverrideInfo, SubmissionInfo
from thermolab.lab.assignments.service import AssignmentDraft, AssignmentService
from thermolab.lab.assignments.standing import Standing

__all__ = [
    "Answers",
    "Assessment",
    "AssignmentDraft",
    "AssignmentInfo",
    "AssignmentService",
    "ExtensionInfo",
    "GradeRow",
    "GroupInfo",
    "OverrideInfo",
    "Standing",
    "SubmissionInfo",
    "Tolerances",
    "assess",
    "grades_csv",
]
