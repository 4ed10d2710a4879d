"""Everything the lab holds about one person, as one JSON document (LGPD/GDPR access).

:func:`personal_data` walks the schema rather than a list: every table with
a column pointing at ``users.id`` gives the person's rows (the account,
logins, API tokens, course places, turns, queue places, runs, hand-ins and
marks, LTI identities), every table without such a column that points at one
of those rows gives its own (a run's samples, commands and results), and the columns
that hold a login name as text (``NAME_COLUMNS``) give the rows that name
the person. A table added later is in the export without a change here.
Secrets stay out: columns whose name says they hold a hash or a secret are
left out of every row.
"""

from __future__ import annotations

import base64
import datetime as dt
import secrets
from collections.abc import Callable
from typing import Any, Literal

from sqlalchemy import Column, ColumnElement, Table, delete, or_, select, update
from sqlalchemy.orm import Session

from thermolab import __version__
from thermolab.errors import ConflictError, NotFoundError
from thermolab.lab.accounts.names import username_form
from thermolab.lab.db import Database
from thermolab.lab.db.models import Base

__all__ = [
    "EXPORT_FORMAT",
    "NAME_COLUMNS",
    "PSEUDONYM_PREFIX",
    "AuditWriter",
    "RunsChoice",
    "forget_person",
    "personal_data",
    "removed_already",
]

PSEUDONYM_PREFIX = "removed-"
"""How a removed person's kept rows are named: the prefix, then 8 hexadecimal digits."""

RunsChoice = Literal["keep", "delete"]
"""What :func:`forget_person` does with a person's runs."""

EXPORT_FORMAT = 1
"""The export document's layout version."""

NAME_COLUMNS: tuple[tuple[str, str], ...] = (
    ("control_sessions", "username"),
    ("control_sessions", "ended_by"),
    ("commands", "username"),
    ("submissions", "username"),
    ("submissions", "handed_in_by"),
    ("grade_overrides", "set_by"),
    ("deadline_extensions", "set_by"),
    ("lab_groups", "created_by"),
    ("assignments", "created_by"),
    ("bookings", "created_by"),
    ("course_settings", "updated_by"),
    ("rig_settings", "updated_by"),
    ("guide_images", "uploaded_by"),
    ("guide_revisions", "author"),
    ("courses", "closed_by"),
)
"""Columns that hold a login name as text rather than a key to ``users``."""

_SECRET_MARKS = ("hash", "secret", "private")


def removed_already() -> ColumnElement[bool]:
    """True of a ``users`` row that is a removed person's, kept under its pseudonym for their runs.

    (:func:`forget_person` with ``runs="keep"``: the pseudonym and no display name.)
    """
    users = Base.metadata.tables["users"]
    return users.c.username.like(f"{PSEUDONYM_PREFIX}________") & users.c.display_name.is_(None)


def personal_data(db: Database, user_id: int, username: str) -> dict[str, Any]:
    """Return every row that is about the person ``user_id`` (login ``username``).

    Returns
    -------
    dict
        ``{"format", "version", "exportedAt", "username", "tables": {name: [row, ...]}}``,
        rows as column -> JSON value (dates in ISO 8601, bytes in base64), the
        tables in dependency order, empty tables left out.
    """
    users = Base.metadata.tables["users"]
    tables: dict[str, list[dict[str, Any]]] = {}
    keys: dict[str, set[Any]] = {"users": {user_id}}
    with db.read() as session:
        for table in Base.metadata.sorted_tables:
            # A row that names a person is theirs only by that name: a course the
            # teacher made does not bring its roster. Other rows follow their parent.
            by_person = [
                column
                for column in table.columns
                if any(key.column.table is users for key in column.foreign_keys)
            ]
            conditions = [column == user_id for column in by_person]
            if not by_person:
                for column in table.columns:
                    for key in column.foreign_keys:
                        found = keys.get(key.column.table.name)
                        if found and key.column.table is not table:
                            conditions.append(column.in_(found))
            if table is users:
                conditions.append(users.c.id == user_id)
            for name, column_name in NAME_COLUMNS:
                if name == table.name and column_name in table.c:
                    conditions.append(table.c[column_name] == username)
            if not conditions:
                continue
            rows = session.execute(select(table).where(or_(*conditions))).mappings().all()
            if not rows:
                continue
            tables[table.name] = [_row(table, row) for row in rows]
            primary = _single_key(table)
            if primary is not None:
                keys[table.name] = {row[primary.name] for row in rows}
    return {
        "format": EXPORT_FORMAT,
        "version": __version__,
        "exportedAt": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "username": username,
        "tables": tables,
    }


def _single_key(table: Table) -> Column[Any] | None:
    columns = list(table.primary_key.columns)
    return columns[0] if len(columns) == 1 else None


def _row(table: Table, row: Any) -> dict[str, Any]:
    return {
        column.name: _json(row[column.name])
        for column in table.columns
        if not any(mark in column.name for mark in _SECRET_MARKS)
    }


def _json(value: Any) -> Any:
    if isinstance(value, dt.datetime | dt.date):
        return value.isoformat()
    if isinstance(value, bytes | bytearray | memoryview):
        return base64.b64encode(bytes(value)).decode("ascii")
    if isinstance(value, float) and value != value:  # NaN is not JSON
        return None
    return value


# Rows that identify a person and serve nothing once they are gone: their logins,
# tokens, LMS identities, pending LMS launches, waiting places, calendar feeds and the
# reminder address. Runs, turns, course places and hand-ins stay (under the pseudonym)
# when runs are kept: a course's statistics count them.
_PERSONAL_TABLES = (
    "sessions",
    "api_tokens",
    "lti_identities",
    "lti_handoffs",
    "queue_entries",
    "calendar_feeds",
    "reminder_addresses",
)


AuditWriter = Callable[[Session, str], None]
"""Writes a removal's audit entry in the removal's transaction: ``(session, pseudonym)``."""


def forget_person(
    db: Database,
    username: str,
    runs: RunsChoice,
    password_hash: str,
    *,
    audit: AuditWriter | None = None,
) -> str:
    """Remove a person: their account goes, their runs are kept under a pseudonym or deleted.

    With ``runs="keep"`` the account's row stays as ``removed-XXXXXXXX`` (no
    display name, a password no one knows) and keeps the runs, turns, course
    places and hand-ins; with ``runs="delete"`` the row and all of those go.
    Either way the login name is replaced by the pseudonym wherever another
    row names the person (``NAME_COLUMNS``, a run's "ended by"), and their
    logins, tokens, LMS identities and pending LMS grades are deleted.

    Parameters
    ----------
    password_hash : str
        The hash of a random password (the caller's hasher): what the kept row holds.
    audit : callable, optional
        Writes the removal's audit entry, given the session and the pseudonym, in
        the removal's own transaction (:meth:`~thermolab.lab.audit.log.AuditLog.forgotten`):
        if the entry cannot be written, nobody is removed.

    Returns
    -------
    str
        The pseudonym.

    Raises
    ------
    NotFoundError
        If there is no such person.
    ConflictError
        If they are at a rig's controls or waiting for one (try when they are done).
    """
    tables = Base.metadata.tables
    users, runs_table = tables["users"], tables["runs"]
    pseudonym = f"{PSEUDONYM_PREFIX}{secrets.token_hex(4)}"
    with db.write() as session:
        user_id = session.scalar(
            select(users.c.id).where(users.c.username == username_form(username))
        )
        if user_id is None:
            raise NotFoundError(f"no user called {username!r}")
        name = session.scalar(select(users.c.username).where(users.c.id == user_id))
        busy = session.scalar(
            select(tables["control_sessions"].c.id).where(
                tables["control_sessions"].c.user_id == user_id,
                tables["control_sessions"].c.ended_at.is_(None),
            )
        ) or session.scalar(
            select(tables["queue_entries"].c.id).where(
                tables["queue_entries"].c.user_id == user_id,
                tables["queue_entries"].c.left_at.is_(None),
            )
        )
        if busy is not None:
            raise ConflictError(
                f"{name} is at a rig's controls or waiting for one; remove them when they are done",
                case="person_at_rig",
            )
        identities = tables["lti_identities"]
        subs = list(
            session.scalars(select(identities.c.sub).where(identities.c.user_id == user_id))
        )
        if subs:
            session.execute(
                delete(tables["lti_grades"]).where(tables["lti_grades"].c.sub.in_(subs))
            )
        for table_name, column_name in NAME_COLUMNS:
            column = tables[table_name].c[column_name]
            session.execute(
                update(column.table).where(column == name).values({column_name: pseudonym})
            )
        session.execute(
            update(runs_table)
            .where(runs_table.c.end_reason == f"ended by {name}")
            .values(end_reason=f"ended by {pseudonym}")
        )
        if runs == "delete":
            session.execute(delete(users).where(users.c.id == user_id))  # the rest cascades
        else:
            for table_name in _PERSONAL_TABLES:
                table = tables[table_name]
                session.execute(delete(table).where(table.c.user_id == user_id))
            session.execute(
                update(users)
                .where(users.c.id == user_id)
                .values(username=pseudonym, display_name=None, password_hash=password_hash)
            )
        if audit is not None:
            audit(session, pseudonym)
    return pseudonym
