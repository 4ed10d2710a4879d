"""Assignments, hand-ins and grades on the database (the API uses this service).

A teacher of a course sets an assignment; a student of the course hands in
one of their own finished runs on the assignment's rig with their answers.
The run is identified again with the assignment's methods
(:mod:`.identify`, outside any transaction: it may take a second), marked
(:func:`.marking.assess`) and stored; every hand-in is kept, the newest is
the current one, a hand-in after the deadline is kept and marked late.

For other parts of the lab (LTI grade passback, analytics):

* :meth:`AssignmentService.grade_rows` — the ``(course, assignment, student,
  mark, max, marked_at, late)`` rows (:class:`~.grades.GradeRow`);
* :meth:`AssignmentService.on_marked` — subscribe to "submission marked":
  the callback gets the new :class:`~.grades.GradeRow` after the hand-in is
  stored, or a teacher's override changes the final mark (a callback's error
  is logged, never undoes the hand-in).

A teacher's tools hang off the service: :attr:`AssignmentService.overrides`
(:mod:`.overrides`), :attr:`AssignmentService.extensions` (:mod:`.extensions`)
and :attr:`AssignmentService.groups` (:mod:`.groups`); a group's hand-in is
stored here, once per member.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from sqlalchemy import or_, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    ConflictError,
    HandInRefusedError,
    InvalidParameterError,
    NotFoundError,
)
from thermolab.lab.accounts.policy import Action
from thermolab.lab.accounts.users import Principal
from thermolab.lab.assignments.extensions import ExtensionService, extensions_of, own_deadline
from thermolab.lab.assignments.grades import GradeRow
from thermolab.lab.assignments.groups import GroupService, group_of, mates
from thermolab.lab.assignments.identify import check_methods, identify_run
from thermolab.lab.assignments.marking import Answers, Tolerances, assess
from thermolab.lab.assignments.overrides import OverrideService, overrides_of
from thermolab.lab.assignments.reference import reference_model
from thermolab.lab.assignments.rows import (
    AssignmentInfo,
    SubmissionInfo,
    assignment_with_course,
    course_named,
    grade_row,
    info,
    override_info,
    submission_info,
    tolerances_of,
)
from thermolab.lab.assignments.standing import Standing, standings
from thermolab.lab.classes.authorize import require_in_course
from thermolab.lab.classes.closed import require_open
from thermolab.lab.classes.course_access import require_member
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.assignment_models import Assignment, Submission
from thermolab.lab.db.models import (
    Course,
    CourseMember,
    MemberRole,
    Role,
    Run,
    RunStatus,
    Sample,
    User,
)
from thermolab.rigs.spec import RigSpec

__all__ = [
    "MIN_SAMPLES",
    "AssignmentDraft",
    "AssignmentInfo",
    "AssignmentService",
    "MarkedListener",
    "SubmissionInfo",
    "assignment_with_course",
]

log = logging.getLogger(__name__)

#: The fewest stored samples a handed-in run may have.
MIN_SAMPLES = 10
MAX_INSTRUCTIONS = 20_000
MAX_CONCLUSION = 4_000

MarkedListener = Callable[[GradeRow], None]


@dataclass(frozen=True, slots=True)
class AssignmentDraft:
    """What a teacher writes: checked by :meth:`AssignmentService.create`."""

    title: str
    instructions: str
    rig: str
    methods: tuple[str, ...]
    deadline: datetime
    tolerances: Tolerances
    settings: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)


class AssignmentService:
    """Set assignments, hand in, mark, list and export grades.

    Parameters
    ----------
    db : Database
    clock : LabClock
    config : LabConfig
        The rigs an assignment may name (and their specs, for the reference model).
    """

    def __init__(self, db: Database, clock: LabClock, config: LabConfig) -> None:
        self._db = db
        self._clock = clock
        self._config = config
        self._listeners: list[MarkedListener] = []
        #: A teacher's tools: marks overridden, deadlines extended, lab groups.
        self.overrides = OverrideService(db, clock, self._tell)
        self.extensions = ExtensionService(db, clock)
        self.groups = GroupService(db, clock)

    def on_marked(self, listener: MarkedListener) -> Callable[[], None]:
        """Call ``listener(row)`` after each hand-in is marked and stored; return an unsubscribe."""
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener)

    # -- teachers ------------------------------------------------------------------------

    def create(self, course: str, who: Principal, draft: AssignmentDraft) -> AssignmentInfo:
        """Set an assignment in ``course`` (a teacher of that course only).

        Raises
        ------
        AccessDeniedError, NotFoundError, InvalidParameterError
        """
        self._check_draft(draft)
        now = self._clock.now()
        with self._db.write() as session:
            found = course_named(session, course)
            require_in_course(session, found, who, Action.COURSE_ASSIGNMENTS_EDIT)
            require_open(found, "set assignments")
            row = Assignment(course_id=found.id, created_by=who.username, created_at=now)
            _fill(row, draft, now)
            session.add(row)
            session.flush()
            return info(row, found)

    def update(self, assignment_id: int, who: Principal, draft: AssignmentDraft) -> AssignmentInfo:
        """Change an assignment (its hand-ins keep the marks they were given)."""
        self._check_draft(draft)
        now = self._clock.now()
        with self._db.write() as session:
            row, found = assignment_with_course(session, assignment_id)
            require_in_course(session, found, who, Action.COURSE_ASSIGNMENTS_EDIT)
            require_open(found, "edit its assignments")
            _fill(row, draft, now)
            session.flush()
            return info(row, found)

    def submissions(self, assignment_id: int, who: Principal) -> list[SubmissionInfo]:
        """Every hand-in of an assignment, current ones first then by student (its teachers)."""
        with self._db.read() as session:
            row, found = assignment_with_course(session, assignment_id)
            require_in_course(session, found, who, Action.COURSE_HAND_INS)
            rows = session.execute(
                select(Submission, User.display_name)
                .join(User, User.id == Submission.user_id)
                .where(Submission.assignment_id == row.id)
                .order_by(Submission.current.desc(), Submission.username, Submission.id.desc())
            ).all()
            return [submission_info(s, name) for s, name in rows]

    def standings(self, assignment_id: int, who: Principal) -> list[Standing]:
        """Each student's final and automatic mark, deadline and group (:mod:`.standing`)."""
        return standings(self._db, assignment_id, who)

    def grade_rows(self, course: str, who: Principal | None = None) -> list[GradeRow]:
        """One row per student × assignment of ``course`` (the current hand-in, or ``missing``).

        This is the function LTI grade passback and analytics read. With
        ``who`` the caller must be a teacher or assistant of the course;
        ``None`` is the lab itself.
        """
        with self._db.read() as session:
            found = course_named(session, course)
            if who is not None:
                require_in_course(session, found, who, Action.COURSE_HAND_INS)
            assignments = list(
                session.scalars(
                    select(Assignment)
                    .where(Assignment.course_id == found.id, Assignment.draft.is_(False))
                    .order_by(Assignment.deadline, Assignment.id)
                )
            )
            students = session.execute(
                select(User.id, User.username, User.display_name)
                .join(CourseMember, CourseMember.user_id == User.id)
                .where(
                    CourseMember.course_id == found.id,
                    CourseMember.role == Role.STUDENT.value,
                )
                .order_by(User.username)
            ).all()
            current = {
                (s.assignment_id, s.user_id): s
                for s in session.scalars(
                    select(Submission).where(
                        Submission.assignment_id.in_([a.id for a in assignments]),
                        Submission.current,
                    )
                )
            }
            overridden = overrides_of(session, [a.id for a in assignments])
            rows = []
            for a in assignments:
                for user_id, username, display in students:
                    s = current.get((a.id, user_id))
                    o = overridden.get((a.id, user_id)) if s is not None else None
                    rows.append(grade_row(found, a, username, display, s, o))
            return rows

    # -- students ------------------------------------------------------------------------

    def for_user(self, who: Principal) -> list[AssignmentInfo]:
        """The assignments of every course ``who`` is in, with their own hand-ins."""
        with self._db.read() as session:
            rows = session.execute(
                select(Assignment, Course)
                .join(Course, Course.id == Assignment.course_id)
                .join(CourseMember, CourseMember.course_id == Course.id)
                .where(
                    CourseMember.user_id == who.user_id,
                    # A draft is its teachers' (and assistants') until they publish it.
                    or_(Assignment.draft.is_(False), CourseMember.role != MemberRole.STUDENT.value),
                )
                .order_by(Assignment.deadline, Assignment.id)
            ).all()
            return [_for_caller(session, a, c, who.user_id) for a, c in rows]

    def get(self, assignment_id: int, who: Principal) -> AssignmentInfo:
        """One assignment, for a member of its course (a student sees their own hand-ins)."""
        with self._db.read() as session:
            row, found = assignment_with_course(session, assignment_id)
            require_member(session, found, who, None, "see its assignments")
            if row.draft:
                require_in_course(session, found, who, Action.COURSE_HAND_INS)
            return _for_caller(session, row, found, who.user_id)

    def hand_in(
        self, assignment_id: int, who: Principal, run_id: int, answers: Answers
    ) -> SubmissionInfo:
        """Hand in one of ``who``'s finished runs on the assignment's rig, with answers.

        The run is identified again and the answers marked; the hand-in
        becomes the student's current one (earlier ones are kept). After the
        student's deadline (their extension's, else the assignment's) it is
        kept and marked late. In a lab group (:mod:`.groups`) the run may be
        any member's and the hand-in is stored for every member.

        Raises
        ------
        AccessDeniedError
            Not a student of the course, or not their (or their group's) run.
        NotFoundError
            No such assignment or run.
        ConflictError
            The run is on another rig, has not finished, or has too few samples.
        InvalidParameterError
            Bad answers.
        """
        _check_answers(answers)
        with self._db.read() as session:
            row, found = assignment_with_course(session, assignment_id)
            require_member(session, found, who, Role.STUDENT, "hand in")
            require_open(found, "hand in")
            if row.draft:
                raise NotFoundError(f"no assignment {assignment_id}")
            run = session.get(Run, run_id)
            if run is None:
                raise NotFoundError(f"no run {run_id}")
            owner = run.user_id  # theirs, or a lab group mate's (checked as it is stored)
            if run.rig_id != row.rig_id:
                raise HandInRefusedError(
                    f"run {run_id} was made on rig {run.rig_id!r}; this assignment is on "
                    f"{row.rig_id!r}",
                    "handin_wrong_rig",
                )
            if run.status != RunStatus.FINISHED.value:
                raise HandInRefusedError(
                    f"run {run_id} is {run.status}, not finished: "
                    "hand in a run that ran to its end",
                    "handin_unfinished",
                )
            samples = session.execute(
                select(Sample.t, Sample.u, Sample.y)
                .where(Sample.run_id == run_id)
                .order_by(Sample.k)
            ).all()
            if len(samples) < MIN_SAMPLES:
                raise HandInRefusedError(
                    f"run {run_id} has {len(samples)} samples; at least {MIN_SAMPLES} are needed",
                    "handin_too_short",
                )
            methods = tuple(row.methods)
            settings = dict(row.settings)
            tolerances = tolerances_of(row)
            dt, rig = run.dt, row.rig_id
        t, u, y = (list(c) for c in zip(*samples, strict=True))
        units = self._units(rig)
        peers: dict[str, dict[str, Any]] = {}  # one output-error fit of the run for all
        identified = [identify_run(m, t, u, y, dt, settings.get(m), units, peers) for m in methods]
        result = assess(answers, tolerances, self._reference(rig), identified)
        now = self._clock.now()
        try:
            with self._db.write() as session:
                row, found = assignment_with_course(session, assignment_id)
                require_open(found, "hand in")
                group = mates(session, found.id, who.user_id)
                if owner not in {user_id for user_id, _ in group}:
                    raise AccessDeniedError(f"run {run_id} is not yours or your lab group's")
                own = extensions_of(session, [row.id])
                overridden = overrides_of(session, [row.id])
                grades, mine = [], None
                for user_id, username in group:  # one hand-in for each member of the group
                    extended = own.get((row.id, user_id))
                    deadline = own_deadline(row, extended)
                    stored = self._store(session, row.id, user_id, username, now, deadline)
                    stored.run_id, stored.answers = run_id, answers.to_dict()
                    stored.state, stored.mark = result.state, result.mark
                    stored.max_mark = result.max
                    stored.assessment = result.to_dict()
                    if user_id != who.user_id:
                        stored.handed_in_by = who.username
                    session.flush()
                    display = session.scalar(select(User.display_name).where(User.id == user_id))
                    o = overridden.get((row.id, user_id))
                    grades.append(grade_row(found, row, username, display, stored, o))
                    if user_id == who.user_id:
                        mine = submission_info(stored, display)
        except IntegrityError:
            raise ConflictError(
                "another hand-in of yours was stored meanwhile; try again", case="stored_meanwhile"
            ) from None
        for grade in grades:
            self._tell(grade)
        assert mine is not None  # the hander is always in their own group
        return mine

    @staticmethod
    def _store(
        session: Session,
        assignment_id: int,
        user_id: int,
        username: str,
        now: datetime,
        deadline: datetime,
    ) -> Submission:
        """A new current hand-in of the student (the earlier current one kept as history)."""
        session.execute(
            update(Submission)
            .where(
                Submission.assignment_id == assignment_id,
                Submission.user_id == user_id,
                Submission.current,
            )
            .values(current=False)
        )
        stored = Submission(
            assignment_id=assignment_id,
            user_id=user_id,
            username=username,
            submitted_at=now,
            late=now > deadline,
            current=True,
            marked_at=now,
        )
        session.add(stored)
        return stored

    def _tell(self, grade: GradeRow) -> None:
        """Tell each "submission marked" listener a student's new grade."""
        for listener in list(self._listeners):
            try:
                listener(grade)
            except Exception:  # a subscriber's fault never undoes a stored hand-in
                log.exception("a 'submission marked' listener failed")

    # -- helpers -------------------------------------------------------------------------

    def _units(self, rig: str) -> tuple[str, str] | None:
        """The rig's input and output units, which the library's words then speak of."""
        for r in self._config.rigs:
            if r.id == rig:
                info = RigSpec.parse(r.spec).describe()
                return info.input_unit, info.output_unit
        return None

    def _reference(self, rig: str) -> Any:
        for r in self._config.rigs:
            if r.id == rig:
                return reference_model(r.spec)
        return None

    def _check_draft(self, draft: AssignmentDraft) -> None:
        if not 0 < len(draft.title.strip()) <= 200:
            raise InvalidParameterError("an assignment's title must have 1 to 200 characters")
        if len(draft.instructions) > MAX_INSTRUCTIONS:
            raise InvalidParameterError(
                f"the instructions must have at most {MAX_INSTRUCTIONS} characters"
            )
        known = {r.id for r in self._config.rigs}
        if draft.rig not in known:
            raise NotFoundError(f"no rig called {draft.rig!r}; rigs: {', '.join(sorted(known))}")
        if not draft.methods:
            raise InvalidParameterError("choose at least one identification method")
        if len(set(draft.methods)) != len(draft.methods):
            raise InvalidParameterError("a method is named twice")
        check_methods(draft.methods, draft.settings)
        if draft.deadline.tzinfo is None:
            raise InvalidParameterError("the deadline must carry its time zone")


def _check_answers(answers: Answers) -> None:
    for name in ("K", "tau"):
        value = getattr(answers, name)
        if not math.isfinite(value):
            raise InvalidParameterError(f"your {name} must be a finite number")
    if answers.tau <= 0:
        raise InvalidParameterError("your time constant Ts must be above 0 s")
    if answers.theta is not None and not (math.isfinite(answers.theta) and answers.theta >= 0):
        raise InvalidParameterError("your dead time θ must be 0 s or more")
    if len(answers.conclusion) > MAX_CONCLUSION:
        raise InvalidParameterError(f"the conclusion must have at most {MAX_CONCLUSION} characters")


def _fill(row: Assignment, draft: AssignmentDraft, now: datetime) -> None:
    row.title = " ".join(draft.title.split())
    row.instructions = draft.instructions
    row.rig_id = draft.rig
    row.methods = list(draft.methods)
    row.settings = {m: dict(s) for m, s in draft.settings.items()}
    row.tol_k = draft.tolerances.K
    row.tol_tau = draft.tolerances.tau
    row.tol_theta = draft.tolerances.theta
    row.deadline = draft.deadline
    row.updated_at = now


def _for_caller(session: Session, a: Assignment, course: Course, user_id: int) -> AssignmentInfo:
    """The assignment with the caller's hand-ins, extension, override and lab group."""
    mine = session.execute(
        select(Submission, User.display_name)
        .join(User, User.id == Submission.user_id)
        .where(Submission.assignment_id == a.id, Submission.user_id == user_id)
        .order_by(Submission.id.desc())
    ).all()
    extended = extensions_of(session, [a.id]).get((a.id, user_id))
    overridden = overrides_of(session, [a.id]).get((a.id, user_id))
    username = mine[0][0].username if mine else ""
    return info(
        a,
        course,
        tuple(submission_info(s, name) for s, name in mine),
        extended_deadline=(
            extended.deadline if extended and extended.deadline > a.deadline else None
        ),
        override=None if overridden is None or not mine else override_info(overridden, username),
        group=group_of(session, course, user_id),
    )
