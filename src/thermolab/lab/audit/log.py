"""Write and read the audit log; its CSV export is formula-safe."""

from __future__ import annotations

import csv
import enum
import io
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.audit_models import AuditEntry
from thermolab.lab.spreadsheets import SheetDialect

__all__ = ["AuditAction", "AuditLog", "AuditRecord"]

MAX_ROWS = 5000


class AuditAction(enum.StrEnum):
    """The privileged actions the log records (stable names, shown as they are)."""

    ACCOUNT_CREATED = "account.created"
    ACCOUNT_REMOVED = "account.removed"
    ACCOUNT_FORGOTTEN = "account.forgotten"
    ACCOUNT_ADMIN = "account.admin"
    PASSWORD_SET = "password.set"
    PASSWORD_RESET = "password.reset"
    COURSE_CREATED = "course.created"
    ROSTER_CHANGED = "course.roster"
    ENROL_CODE_ROTATED = "course.enrol_code"
    COURSE_RIGS_SET = "course.rigs"
    ASSISTANT_ADDED = "course.assistant_added"
    ASSISTANT_REMOVED = "course.assistant_removed"
    COURSE_CLOSED = "course.closed"
    COURSE_REOPENED = "course.reopened"
    COURSE_COPIED = "course.copied"
    COURSE_STUDENTS_PURGED = "course.students_purged"
    ASSIGNMENT_PUBLISHED = "assignment.published"
    LMS_ROSTER_SYNCED = "course.lms_roster"
    ASSIGNMENT_CHANGED = "assignment.changed"
    GRADE_RETRIED = "grade.retry"
    MARK_OVERRIDDEN = "assignment.mark_overridden"
    MARK_OVERRIDE_REMOVED = "assignment.mark_override_removed"
    DEADLINE_EXTENDED = "assignment.deadline_extended"
    EXTENSION_REMOVED = "assignment.extension_removed"
    GROUP_CREATED = "course.group_created"
    GROUP_REMOVED = "course.group_removed"
    RIG_SETTINGS_CHANGED = "rig.settings"
    RIG_SERVICE = "rig.service"
    LTI_PLATFORM_ADDED = "lti.platform_added"
    LTI_PLATFORM_REMOVED = "lti.platform_removed"
    LTI_KEY_ROTATED = "lti.key_rotated"


@dataclass(frozen=True, slots=True)
class AuditRecord:
    """One row of the log."""

    id: int
    at: datetime
    actor: str
    action: str
    target: str
    address: str | None
    detail: Mapping[str, Any] = field(default_factory=dict)


class AuditLog:
    """Append privileged actions; list them for administrators.

    Parameters
    ----------
    db : Database
    clock : LabClock
    """

    def __init__(self, db: Database, clock: LabClock) -> None:
        self._db = db
        self._clock = clock

    def record(
        self,
        actor: str,
        action: AuditAction,
        target: str,
        *,
        address: str | None = None,
        detail: Mapping[str, Any] | None = None,
    ) -> None:
        """Append one row: ``actor`` did ``action`` on ``target`` from ``address``."""
        with self._db.write() as session:
            session.add(self._entry(actor, action, target, address, detail))

    def _entry(
        self,
        actor: str,
        action: AuditAction,
        target: str,
        address: str | None,
        detail: Mapping[str, Any] | None,
    ) -> AuditEntry:
        return AuditEntry(
            at=self._clock.now(),
            actor=actor[:64],
            action=action.value,
            target=target[:200],
            address=(address or None) and address[:64],
            detail=dict(detail or {}),
        )

    def forgotten(
        self, actor: str, *, address: str | None = None, **detail: Any
    ) -> Callable[[Session, str], None]:
        """The entry of a removal (``account.forgotten``), for the removal to write itself.

        :func:`~thermolab.lab.accounts.personal_data.forget_person` calls it with
        its session and the pseudonym, so that nobody is removed unlogged.
        """

        def write(session: Session, pseudonym: str) -> None:
            # In the removal's transaction: the entry stands or falls with it.
            forgotten = AuditAction.ACCOUNT_FORGOTTEN
            session.add(self._entry(actor, forgotten, pseudonym, address, detail))

        return write

    def list(
        self,
        *,
        action: str | None = None,
        actor: str | None = None,
        since: datetime | None = None,
        limit: int = 500,
    ) -> list[AuditRecord]:
        """Return the newest rows first, at most ``limit`` (capped at 5000)."""
        query = select(AuditEntry).order_by(AuditEntry.id.desc()).limit(min(limit, MAX_ROWS))
        if action is not None:
            query = query.where(AuditEntry.action == action)
        if actor is not None:
            query = query.where(AuditEntry.actor == actor)
        if since is not None:
            query = query.where(AuditEntry.at >= since)
        with self._db.read() as session:
            return [
                AuditRecord(e.id, e.at, e.actor, e.action, e.target, e.address, e.detail or {})
                for e in session.scalars(query)
            ]

    @staticmethod
    def to_csv(records: Iterable[AuditRecord], dialect: SheetDialect | None = None) -> str:
        """The rows as CSV; a cell a spreadsheet would run as a formula is quoted with ``'``.

        With ``dialect``, the spreadsheet form: headings in the language, local
        times; the actions stay the stable names the audit page shows.
        """
        if dialect is not None:
            header = [dialect.word("No."), dialect.timed("When")]
            header += [dialect.word(w) for w in ("Who", "Action", "About", "From where", "Detail")]
            return dialect.document(
                header,
                (
                    [r.id, r.at, r.actor, r.action, r.target, r.address, _detail(r.detail)]
                    for r in records
                ),
            )
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\r\n")
        writer.writerow(["id", "at", "actor", "action", "target", "address", "detail"])
        for r in records:
            detail = _detail(r.detail)
            writer.writerow(
                [
                    r.id,
                    r.at.isoformat(),
                    *(_safe(v) for v in (r.actor, r.action, r.target, r.address or "", detail)),
                ]
            )
        return out.getvalue()


def _detail(detail: Mapping[str, Any]) -> str:
    return "; ".join(f"{k}={v}" for k, v in sorted(detail.items()))


def _safe(cell: str) -> str:
    # CSV injection: a leading = + - @ (or tab/CR) makes a spreadsheet run the cell.
    return "'" + cell if cell[:1] in ("=", "+", "-", "@", "\t", "\r") else cell
