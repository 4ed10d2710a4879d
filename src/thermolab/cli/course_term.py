"""``thermolab course close|reopen|copy|purge-students``: the end of a term from the shell.

The command line is the operator's: it acts as a lab administrator would
(:mod:`thermolab.lab.classes.term` does the work, as for the API).

* ``close COURSE [--by NAME]``: read-only from now on, its bookings that have not
  begun cancelled; ``reopen COURSE`` undoes the close (not the cancellations).
* ``copy OLD NEW (--shift-days N | --starts YYYY-MM-DD) [--title T] [--teacher NAME]``:
  the next term's course, its only teacher ``--teacher`` (default: the old
  course's first teacher by name); the slots left out are listed.
* ``purge-students COURSE [--delete-runs] [--yes]``: without ``--yes`` only lists
  who would go (a dry run); with it, removes them (runs kept under a pseudonym
  unless ``--delete-runs``), each removal written to the audit log.
"""

from __future__ import annotations

import argparse
import secrets
import sys
from datetime import date
from typing import TYPE_CHECKING, Any

from thermolab.cli._words import _, library_text
from thermolab.cli.serve import add_database_options, lab_config_from_args, make_private

if TYPE_CHECKING:
    from thermolab.lab.accounts.users import Principal
    from thermolab.lab.classes.term import TermService
    from thermolab.lab.clock import LabClock
    from thermolab.lab.db import Database

__all__ = ["add_actions"]

#: Who the audit log and ``closed_by`` name when the operator acts from the shell.
OPERATOR = "(command line)"


def add_actions(actions: Any) -> None:
    """Add the end-of-term actions to ``thermolab course``'s subparsers."""
    close = actions.add_parser("close", help=_("close a course at the end of its term (read-only)"))
    close.add_argument("course", metavar="COURSE")
    close.add_argument("--by", metavar="NAME", help=_("whose decision it was (a login name)"))
    add_database_options(close)
    close.set_defaults(handler=_close)

    reopen = actions.add_parser("reopen", help=_("open a closed course again"))
    reopen.add_argument("course", metavar="COURSE")
    add_database_options(reopen)
    reopen.set_defaults(handler=_reopen)

    copy = actions.add_parser(
        "copy",
        help=_("make the next term's course from one (rigs, limits, draft assignments, bookings)"),
    )
    copy.add_argument("old", metavar="OLD")
    copy.add_argument("new", metavar="NEW", help=_("the new course's short name"))
    when = copy.add_mutually_exclusive_group(required=True)
    when.add_argument("--shift-days", type=int, metavar="N", help=_("move every date by N days"))
    when.add_argument(
        "--starts",
        type=_day,
        metavar="YYYY-MM-DD",
        help=_("the new term's first day: OLD's first booked day (else its creation) moves there"),
    )
    copy.add_argument("--title", help=_("the new title (default: OLD's)"))
    copy.add_argument(
        "--teacher", metavar="NAME", help=_("the copy's teacher (default: OLD's first teacher)")
    )
    add_database_options(copy)
    copy.set_defaults(handler=_copy)

    purge = actions.add_parser(
        "purge-students",
        help=_(
            "remove a closed course's students who are in no open course (dry run without --yes)"
        ),
    )
    purge.add_argument("course", metavar="COURSE")
    purge.add_argument(
        "--delete-runs",
        action="store_true",
        help=_(
            "delete their runs too (default: kept under a pseudonym for the class's statistics)"
        ),
    )
    purge.add_argument("--yes", action="store_true", help=_("remove them (without it: only list)"))
    add_database_options(purge)
    purge.set_defaults(handler=_purge)


def _day(text: str) -> date:
    try:
        return date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            _("{text} is not a day written YYYY-MM-DD").format(text=repr(text))
        ) from None


def _term(args: argparse.Namespace) -> tuple[Database, TermService, LabClock]:
    from thermolab.lab.classes.bookings import BookingService
    from thermolab.lab.classes.term import TermService
    from thermolab.lab.clock import SystemClock
    from thermolab.lab.db import Database

    config = lab_config_from_args(args)
    for path in make_private(config):
        print(
            _("warning: tightened permissions of {path} to this user only").format(path=path),
            file=sys.stderr,
        )
    db = Database(config.database, pool_size=1, max_overflow=1)
    db.upgrade()
    clock = SystemClock()
    return db, TermService(db, clock, BookingService(db, clock, config)), clock


def _close(args: argparse.Namespace) -> int:
    from thermolab.lab.audit.log import AuditAction, AuditLog

    db, term, clock = _term(args)
    try:
        released = term.close(args.course, args.by or OPERATOR)
        AuditLog(db, clock).record(
            OPERATOR,
            AuditAction.COURSE_CLOSED,
            args.course,
            detail={"released_bookings": released},
        )
    finally:
        db.close()
    said = _(
        "closed course {course}: it can be read and exported, not changed; "
        "{released} bookings that had not begun were cancelled, freeing their rigs"
    )
    print(said.format(course=repr(args.course), released=released))
    return 0


def _reopen(args: argparse.Namespace) -> int:
    from thermolab.lab.audit.log import AuditAction, AuditLog

    db, term, clock = _term(args)
    try:
        term.reopen(args.course)
        AuditLog(db, clock).record(OPERATOR, AuditAction.COURSE_REOPENED, args.course)
    finally:
        db.close()
    print(_("reopened course {course}").format(course=repr(args.course)))
    return 0


def _copy(args: argparse.Namespace) -> int:
    from thermolab.lab.audit.log import AuditAction, AuditLog

    db, term, clock = _term(args)
    try:
        teacher = _teacher(db, args.old, args.teacher)
        shift = args.shift_days
        if shift is None:
            shift = term.shift_for(args.old, args.starts)
        report = term.copy(args.old, args.new, args.title, teacher, shift)
        AuditLog(db, clock).record(
            OPERATOR,
            AuditAction.COURSE_COPIED,
            report.course,
            detail={"source": args.old, "shift_days": shift, "teacher": teacher.username},
        )
    finally:
        db.close()
    said = _(
        "copied {old} to {new} (teacher {teacher}, dates moved {days} days): "
        "{assignments} draft assignments, {bookings} bookings"
    )
    print(
        said.format(
            old=repr(args.old),
            new=repr(report.course),
            teacher=teacher.username,
            days=report.shift_days,
            assignments=report.assignments,
            bookings=report.bookings,
        )
    )
    for slot in report.skipped:
        left_out = _("left out the slot {starts}-{ends} UTC: {reason}")
        print(
            "  "
            + left_out.format(
                starts=f"{slot.starts_at:%Y-%m-%d %H:%M}",
                ends=f"{slot.ends_at:%H:%M}",
                reason=library_text(slot.reason),
            )
        )
    return 0


def _purge(args: argparse.Namespace) -> int:
    from thermolab.lab.accounts.personal_data import RunsChoice
    from thermolab.lab.accounts.security import default_password_hasher
    from thermolab.lab.audit.log import AuditAction, AuditLog

    runs: RunsChoice = "delete" if args.delete_runs else "keep"
    db, term, clock = _term(args)
    try:
        leavers = term.leavers(args.course)
        if not args.yes or not leavers:
            for person in leavers:
                print(f"{person.username}\t{person.display_name or ''}")
            if not leavers:
                said = _("{count} students of {course} are in no open course")
            elif runs == "delete":
                said = _(
                    "{count} students of {course} are in no open course; "
                    "to remove them (runs deleted), add --yes"
                )
            else:
                said = _(
                    "{count} students of {course} are in no open course; "
                    "to remove them (runs kept under a pseudonym), add --yes"
                )
            print(said.format(count=len(leavers), course=repr(args.course)), file=sys.stderr)
            return 0
        unknown = default_password_hasher().hash(secrets.token_urlsafe(32))
        audit = AuditLog(db, clock)
        names = [p.username for p in leavers]
        written = audit.forgotten(OPERATOR, runs=runs)
        report = term.purge(args.course, names, runs, unknown, audit=written)
        audit.record(
            OPERATOR,
            AuditAction.COURSE_STUDENTS_PURGED,
            args.course,
            detail={"runs": runs, "removed": report.removed, "skipped": len(report.skipped)},
        )
    finally:
        db.close()
    if runs == "delete":
        removed = _("removed {count} students of {course} (runs delete)")
    else:
        removed = _("removed {count} students of {course} (runs keep)")
    print(removed.format(count=len(report.removed), course=repr(args.course)))
    for username, reason in report.skipped.items():
        left = _("left {username}: {reason}")
        print("  " + left.format(username=username, reason=library_text(reason)), file=sys.stderr)
    return 1 if report.skipped else 0


def _teacher(db: Database, course: str, name: str | None) -> Principal:
    from sqlalchemy import select

    from thermolab.errors import NotFoundError
    from thermolab.lab.accounts.names import username_form
    from thermolab.lab.accounts.users import Principal
    from thermolab.lab.db.models import Course, CourseMember, Role, User

    with db.read() as session:
        if session.scalar(select(Course.id).where(Course.name == course.strip().lower())) is None:
            raise NotFoundError(f"no course called {course!r}")
        query = select(User).where(User.role == Role.TEACHER.value)
        if name is not None:
            query = query.where(User.username == username_form(name))
        else:
            query = (
                query.join(CourseMember, CourseMember.user_id == User.id)
                .join(Course, Course.id == CourseMember.course_id)
                .where(Course.name == course.strip().lower())
                .where(CourseMember.role == Role.TEACHER.value)
                .order_by(User.username)
            )
        user = session.scalars(query.limit(1)).one_or_none()
        if user is None:
            raise NotFoundError(
                f"no teacher called {name!r}"
                if name
                else f"course {course!r} has no teacher; name the copy's teacher with --teacher"
            )
        return Principal(user.id, user.username, Role(user.role), admin=user.admin)
