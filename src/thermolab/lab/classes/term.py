"""The end of a term and the next one: close a course, copy it, remove last term's students.

* :meth:`TermService.close` makes a course read-only (when and by whom are
  kept); every change to it is then a 409 ``course_closed``
  (:func:`thermolab.lab.classes.closed.require_open`). Its bookings that have
  not begun are cancelled in the same transaction, so that other courses may
  book those rigs; a slot under way stays to its end. An administrator
  :meth:`~TermService.reopen`\\ s it; the cancelled bookings do not come back.
* :meth:`TermService.copy` makes the next term's course from it: the rigs it
  may use, its limits, its assignments as drafts (deadlines shifted), its
  booking pattern shifted to the new dates; no students, runs, hand-ins or
  marks. Guide pages and their pictures belong to the rigs, not the course, so
  the copy shows the same ones.
* :meth:`TermService.leavers` and :meth:`TermService.purge` remove, in one
  action, the students of a closed course who are in no open course, each
  through :func:`thermolab.lab.accounts.personal_data.forget_person`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import date, datetime, timedelta

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    BookingClashError,
    ConflictError,
    CourseNameTakenError,
    InvalidParameterError,
    NotFoundError,
    RigBookedError,
)
from thermolab.lab.accounts.personal_data import (
    AuditWriter,
    RunsChoice,
    forget_person,
    removed_already,
)
from thermolab.lab.accounts.users import Principal
from thermolab.lab.assignments.service import assignment_with_course
from thermolab.lab.classes.bookings import BookingService
from thermolab.lab.classes.closed import require_open
from thermolab.lab.classes.course_access import course_named, require_member
from thermolab.lab.classes.course_names import COURSE_NAME, new_enrol_code
from thermolab.lab.classes.slot_times import MAX_SLOT_HOURS
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.assignment_models import Assignment
from thermolab.lab.db.booking_models import Booking, BookingRig
from thermolab.lab.db.booking_tool_models import CourseBookingQuota
from thermolab.lab.db.course_settings_models import CourseSettingsRow
from thermolab.lab.db.models import Course, CourseMember, CourseRig, Role, User

__all__ = ["CopyReport", "Leaver", "PurgeReport", "SkippedSlot", "TermService"]

#: The farthest a copy moves its dates (about two years either way).
MAX_SHIFT_DAYS = 800


@dataclass(frozen=True, slots=True)
class SkippedSlot:
    """A booking of the old course not made for the copy, and why (a sentence)."""

    starts_at: datetime
    ends_at: datetime
    reason: str


@dataclass(slots=True)
class CopyReport:
    """What a copy made: the new course's name, the offset, counts, and the slots left out."""

    course: str
    shift_days: int
    assignments: int = 0
    bookings: int = 0
    skipped: list[SkippedSlot] = field(default_factory=list)


@dataclass(frozen=True, slots=True)
class Leaver:
    """A student of a closed course who is in no open course."""

    username: str
    display_name: str | None


@dataclass(slots=True)
class PurgeReport:
    """Who was removed (their pseudonyms) and who could not be (name and reason)."""

    removed: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)


class TermService:
    """Close, reopen and copy courses; remove a closed course's leaving students.

    Parameters
    ----------
    db : Database
    clock : LabClock
    bookings : BookingService
        Makes the copy's bookings, with the same checks and rig locks as a teacher's.
    """

    def __init__(self, db: Database, clock: LabClock, bookings: BookingService) -> None:
        self._db = db
        self._clock = clock
        self._bookings = bookings

    def close(self, name: str, by: str) -> int:
        """Close ``name`` for the term: from now on it is read, exported, never changed.

        ``by`` is the login name of whoever closes it (kept beside the time).
        The course's bookings that start from now on are cancelled (a closed
        course can book nothing, so they would only keep its rigs from other
        courses); one under way stays to its end.

        Returns
        -------
        int
            How many bookings were cancelled.

        Raises
        ------
        NotFoundError
        CourseClosedError
            If it is closed already.
        """
        with self._db.write() as session:
            course = course_named(session, name)
            require_open(course, "close it again")
            now = self._clock.now()
            course.closed_at = now
            course.closed_by = by
            return self._cancel_future_bookings(session, course, now)

    def reopen(self, name: str) -> None:
        """Open a closed course again (an administrator's decision, checked by the route).

        The bookings its close cancelled stay cancelled: their slots may be
        another course's by now; its teachers book again.

        Raises
        ------
        NotFoundError
        ConflictError
            If it is open.
        """
        with self._db.write() as session:
            course = course_named(session, name)
            if course.closed_at is None:
                raise ConflictError(
                    f"course {course.name!r} is open; only a closed one reopens", case="course_open"
                )
            course.closed_at = None
            course.closed_by = None

    def _cancel_future_bookings(self, session: Session, course: Course, now: datetime) -> int:
        future = Booking.course_id == course.id, Booking.starts_at >= now
        rigs = session.scalars(
            select(BookingRig.rig_id)
            .join(Booking, Booking.id == BookingRig.booking_id)
            .where(*future)
            .distinct()
        )
        # The rig locks every booking change takes, in the same (sorted) order.
        for rig in sorted(rigs):
            self._db.lock_rig(session, rig)
        doomed = list(session.scalars(select(Booking).where(*future)))
        for booking in doomed:
            session.delete(booking)  # its rigs' rows cascade
        return len(doomed)

    def shift_for(self, name: str, starts: date) -> int:
        """The days from ``name``'s first day (first booking, else creation) to ``starts``."""
        with self._db.read() as session:
            course = course_named(session, name)
            first = session.scalar(
                select(Booking.starts_at)
                .where(Booking.course_id == course.id)
                .order_by(Booking.starts_at)
                .limit(1)
            )
            began = (first or course.created_at).date()
        return (starts - began).days

    def copy(
        self, old: str, new: str, title: str | None, who: Principal, shift_days: int
    ) -> CopyReport:
        """Make the next term's course ``new`` from ``old``, its dates moved by ``shift_days``.

        The copy is ``who``'s (its only teacher). Rigs, limits and assignments
        (as drafts, deadlines shifted) are made in one transaction; then each
        booking, shifted, through :class:`BookingService` — one that is over,
        clashes with another course's or names a rig the lab no longer has is
        left out and reported.

        Raises
        ------
        InvalidParameterError
            A bad name or title, or a shift beyond :data:`MAX_SHIFT_DAYS`.
        NotFoundError
            No course ``old``.
        CourseNameTakenError
            ``new`` exists.
        AccessDeniedError
            ``who`` is a student.
        """
        cleaned = new.strip().lower()
        if not COURSE_NAME.fullmatch(cleaned):
            raise InvalidParameterError(
                f"course name {new!r} is not valid: use 1 to 64 letters, digits, '.', '_' or '-'"
            )
        if abs(shift_days) > MAX_SHIFT_DAYS:
            raise InvalidParameterError(
                f"a copy moves its dates by at most {MAX_SHIFT_DAYS} days, not {shift_days}"
            )
        if not who.is_teacher:
            raise AccessDeniedError("only a teacher may copy a course; the copy is theirs")
        shift = timedelta(days=shift_days)
        now = self._clock.now()
        report = CopyReport(cleaned, shift_days)
        try:
            with self._db.write() as session:
                source = course_named(session, old)
                if session.scalar(select(Course.id).where(Course.name == cleaned)) is not None:
                    raise CourseNameTakenError("taken.course_choose", cleaned)
                shown = " ".join((title if title is not None else source.title).split())
                if not 0 < len(shown) <= 200:
                    raise InvalidParameterError("a course title must have 1 to 200 characters")
                copy = Course(
                    name=cleaned, title=shown, enrol_code=new_enrol_code(), created_at=now
                )
                session.add(copy)
                session.flush()
                session.add(
                    CourseMember(
                        course_id=copy.id,
                        user_id=who.user_id,
                        role=Role.TEACHER.value,
                        joined_at=now,
                    )
                )
                for rig in session.scalars(
                    select(CourseRig.rig_id).where(CourseRig.course_id == source.id)
                ):
                    session.add(CourseRig(course_id=copy.id, rig_id=rig))
                limits = session.get(CourseSettingsRow, source.id)
                if limits is not None:
                    session.add(
                        CourseSettingsRow(
                            course_id=copy.id,
                            values=dict(limits.values),
                            version=1,
                            updated_at=now,
                            updated_by=who.username,
                        )
                    )
                quota = session.get(CourseBookingQuota, source.id)
                if quota is not None:  # students' own bookings: the same weekly minutes
                    session.add(
                        CourseBookingQuota(
                            course_id=copy.id,
                            minutes_per_week=quota.minutes_per_week,
                            updated_at=now,
                            updated_by=who.username,
                        )
                    )
                for a in session.scalars(
                    select(Assignment)
                    .where(Assignment.course_id == source.id)
                    .order_by(Assignment.id)
                ):
                    session.add(_draft_of(a, copy.id, who.username, now, shift))
                    report.assignments += 1
                slots = [
                    (b.starts_at + shift, b.ends_at + shift, b.note, b.id)
                    for b in session.scalars(
                        select(Booking)
                        # Students' own bookings stay with their term (the copy has no students).
                        .where(Booking.course_id == source.id, Booking.booked_for.is_(None))
                        .order_by(Booking.starts_at)
                    )
                ]
                rigs = {
                    booking: sorted(
                        session.scalars(
                            select(BookingRig.rig_id).where(BookingRig.booking_id == booking)
                        )
                    )
                    for *_, booking in slots
                }
        except IntegrityError:
            raise CourseNameTakenError("taken.course_choose", cleaned) from None
        for starts_at, ends_at, note, booking in slots:
            try:
                longer = ends_at - starts_at > timedelta(hours=MAX_SLOT_HOURS)  # said so then
                self._bookings.create(
                    who, cleaned, rigs[booking], starts_at, ends_at, note, longer=longer
                )
                report.bookings += 1
            except (BookingClashError, RigBookedError, InvalidParameterError, NotFoundError) as exc:
                report.skipped.append(SkippedSlot(starts_at, ends_at, str(exc)))
        return report

    def publish(self, assignment_id: int, who: Principal) -> None:
        """Publish a draft assignment: its course's students see it and may hand in.

        Raises
        ------
        NotFoundError, AccessDeniedError, CourseClosedError
        """
        with self._db.write() as session:
            row, course = assignment_with_course(session, assignment_id)
            require_member(session, course, who, Role.TEACHER, "publish its assignments")
            require_open(course, "publish its assignments")
            row.draft = False
            row.updated_at = self._clock.now()

    def leavers(self, name: str) -> list[Leaver]:
        """The students of the closed course ``name`` who are in no open course, by name.

        Raises
        ------
        NotFoundError
        ConflictError
            If the course is open (close it first: its students are this term's).
        """
        with self._db.read() as session:
            return _leavers(session, _closed(session, name))

    def purge(
        self,
        name: str,
        expected: list[str],
        runs: RunsChoice,
        password_hash: str,
        *,
        audit: AuditWriter | None = None,
    ) -> PurgeReport:
        """Remove the leavers of the closed course ``name``, each as an administrator's removal.

        ``expected`` is the list the administrator was shown (:meth:`leavers`):
        if it is not today's list nobody is removed, so no one leaves unseen.
        A person at a rig's controls or waiting for one is left (and named in
        ``skipped``); the others are removed one by one.

        Raises
        ------
        NotFoundError
        ConflictError
            An open course, or a list that changed since it was shown.
        """
        with self._db.read() as session:
            found = [p.username for p in _leavers(session, _closed(session, name))]
        if sorted(set(expected)) != found:
            raise ConflictError(
                f"the students to remove from {name!r} changed since the list was shown "
                f"({len(found)} now); look at the list again",
                case="leavers_changed",
            )
        report = PurgeReport()
        for username in found:
            try:
                report.removed.append(
                    forget_person(self._db, username, runs, password_hash, audit=audit)
                )
            except (ConflictError, NotFoundError) as exc:
                report.skipped[username] = str(exc)
        return report


def _closed(session: Session, name: str) -> Course:
    course = course_named(session, name)
    if course.closed_at is None:
        raise ConflictError(
            f"course {course.name!r} is open: close it before removing its students",
            case="course_open",
        )
    return course


def _leavers(session: Session, course: Course) -> list[Leaver]:
    open_places = (
        select(CourseMember.user_id)
        .join(Course, Course.id == CourseMember.course_id)
        .where(Course.closed_at.is_(None))
    )
    rows = session.execute(
        select(User.username, User.display_name)
        .join(CourseMember, CourseMember.user_id == User.id)
        .where(
            CourseMember.course_id == course.id,
            CourseMember.role == Role.STUDENT.value,
            User.role == Role.STUDENT.value,
            User.id.not_in(open_places),
            ~removed_already(),
        )
        .order_by(User.username)
    ).all()
    return [Leaver(username, display) for username, display in rows]


def _draft_of(
    a: Assignment, course_id: int, by: str, now: datetime, shift: timedelta
) -> Assignment:
    return Assignment(
        course_id=course_id,
        title=a.title,
        instructions=a.instructions,
        rig_id=a.rig_id,
        methods=list(a.methods),
        settings=dict(a.settings),
        tol_k=a.tol_k,
        tol_tau=a.tol_tau,
        tol_theta=a.tol_theta,
        deadline=a.deadline + shift,
        created_by=by,
        created_at=now,
        updated_at=now,
        draft=True,
    )
