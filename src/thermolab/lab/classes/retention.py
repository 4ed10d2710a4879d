"""Retention: people of courses closed long ago are removed, as the operator chose.

With a retention period of N months (:class:`~thermolab.lab.config.retention.RetentionPolicy`),
a student whose courses are all closed, the last of them more than N months
ago, is removed through the same path as an administrator's removal
(:func:`thermolab.lab.accounts.personal_data.forget_person`): pseudonymised
(runs kept under a pseudonym) or deleted with their runs, as the policy says.
Each removal is written to the audit log (``account.forgotten``, under the
pseudonym, by :data:`ACTOR`). A student in an open course, or in a course
closed within the period, stays; so do teachers and people in no course (they
are no course's leavers). Without a period nothing is ever removed.

``thermolab retention apply [--dry-run]`` runs it from the shell; the server
runs it at its start and then daily (:func:`thermolab.lab.http.app.create_app`).
"""

from __future__ import annotations

import calendar
import secrets
from dataclasses import dataclass, field
from datetime import datetime

from argon2 import PasswordHasher
from sqlalchemy import func, select

from thermolab.errors import ConflictError, NotFoundError
from thermolab.lab.accounts.personal_data import RunsChoice, forget_person, removed_already
from thermolab.lab.audit.log import AuditLog
from thermolab.lab.clock import LabClock
from thermolab.lab.config.retention import RetentionPolicy
from thermolab.lab.db import Database
from thermolab.lab.db.models import Course, CourseMember, Role, User

__all__ = ["ACTOR", "Expired", "RetentionReport", "RetentionService", "months_before"]

ACTOR = "(retention)"
"""Who the audit log names for an automatic removal."""


@dataclass(frozen=True, slots=True)
class Expired:
    """A student past the retention period: their login name and when their last course closed."""

    username: str
    last_closed: datetime


@dataclass(slots=True)
class RetentionReport:
    """One pass: the policy's cut-off, who was due, the pseudonyms removed, who was left and why.

    ``cutoff`` is ``None`` when no retention period is set (nothing was looked at).
    """

    cutoff: datetime | None
    due: list[Expired] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)


def months_before(t: datetime, months: int) -> datetime:
    """The same moment ``months`` calendar months before ``t`` (the day clamped to the month's).

    Examples
    --------
    >>> months_before(datetime(2027, 3, 31, 12), 1)
    datetime.datetime(2027, 2, 28, 12, 0)
    >>> months_before(datetime(2027, 1, 15), 13)
    datetime.datetime(2025, 12, 15, 0, 0)
    """
    year, month = divmod(t.year * 12 + t.month - 1 - months, 12)
    month += 1
    return t.replace(year=year, month=month, day=min(t.day, calendar.monthrange(year, month)[1]))


class RetentionService:
    """Find and remove the people past the lab's retention period.

    Parameters
    ----------
    db : Database
    clock : LabClock
    policy : RetentionPolicy
    audit : AuditLog
        Where each removal is written.
    hasher : PasswordHasher
        Hashes the random password a pseudonymised account's row keeps.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        policy: RetentionPolicy,
        audit: AuditLog,
        hasher: PasswordHasher,
    ) -> None:
        self._db = db
        self._clock = clock
        self.policy = policy
        self._audit = audit
        self._hasher = hasher

    def due(self) -> RetentionReport:
        """Who a pass would remove now, by login name (a dry run: nothing changes)."""
        months = self.policy.months
        if months is None:
            return RetentionReport(None)
        cutoff = months_before(self._clock.now(), months)
        places = (
            select(
                CourseMember.user_id.label("user_id"),
                func.count().label("courses"),
                func.count(Course.closed_at).label("closed"),
                func.max(Course.closed_at).label("last_closed"),
            )
            .join(Course, Course.id == CourseMember.course_id)
            .where(CourseMember.role == Role.STUDENT.value)
            .group_by(CourseMember.user_id)
            .subquery()
        )
        teaching = select(CourseMember.user_id).where(CourseMember.role != Role.STUDENT.value)
        with self._db.read() as session:
            rows = session.execute(
                select(User.username, places.c.last_closed)
                .join(places, places.c.user_id == User.id)
                .where(
                    User.role == Role.STUDENT.value,
                    User.id.not_in(teaching),
                    places.c.courses == places.c.closed,
                    places.c.last_closed < cutoff,
                    ~removed_already(),
                )
                .order_by(User.username)
            ).all()
        return RetentionReport(cutoff, [Expired(name, closed) for name, closed in rows])

    def apply(self) -> RetentionReport:
        """Remove everyone :meth:`due` names, each written to the audit log.

        Someone at a rig's controls or waiting for one is left (in ``skipped``)
        until the next pass; someone removed meanwhile by another process is
        passed over.
        """
        report = self.due()
        if not report.due:
            return report
        runs: RunsChoice = "keep" if self.policy.action == "pseudonymise" else "delete"
        unknown = self._hasher.hash(secrets.token_urlsafe(32))
        for person in report.due:
            audit = self._audit.forgotten(
                ACTOR,
                runs=runs,
                retention_months=self.policy.months,
                last_course_closed=person.last_closed.date().isoformat(),
            )
            try:
                pseudonym = forget_person(self._db, person.username, runs, unknown, audit=audit)
            except NotFoundError:
                continue
            except ConflictError as exc:
                report.skipped[person.username] = str(exc)
                continue
            report.removed.append(pseudonym)
        return report
