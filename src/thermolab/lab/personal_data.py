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
from typing import Any

from sqlalchemy import Column, Table, or_, select

from thermolab import __version__
from thermolab.lab.db import Database
from thermolab.lab.db.models import Base

__all__ = ["EXPORT_FORMAT", "NAME_COLUMNS", "personal_data"]

EXPORT_FORMAT = 1
"""The export document's layout version."""

NAME_COLUMNS: tuple[tuple[str, str], ...] = (
    ("control_sessions", "username"),
    ("control_sessions", "ended_by"),
    ("commands", "username"),
)
"""Columns that hold a login name as text rather than a key to ``users``."""

_SECRET_MARKS = ("hash", "secret", "private")


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
