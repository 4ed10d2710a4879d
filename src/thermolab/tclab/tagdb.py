"""``TagDB``: the historian's SQLite database of tag values by session (``tclab.historian.TagDB``).

The ``tclab`` package's interface (``new_session``, ``get_sessions``,
``delete_session``, ``record``, ``get``, ``clean``, ``close``) on a layout of
our own, readable with plain SQL:

* ``sessions(id, started, columns)`` — ``started`` an ISO 8601 UTC time,
  ``columns`` the JSON list of the historian's columns (``Time`` first);
* ``log(session, time, name, value)`` — one value of one tag at one time
  (lab seconds since the session began). SQLite stores NaN as NULL.
"""

from __future__ import annotations

import datetime
import json
import math
import sqlite3
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = ["TagDB"]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS sessions (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    started TEXT NOT NULL,
    columns TEXT NOT NULL DEFAULT '[]'
);
CREATE TABLE IF NOT EXISTS log (
    session INTEGER NOT NULL REFERENCES sessions (id),
    time REAL NOT NULL,
    name TEXT NOT NULL,
    value
);
CREATE INDEX IF NOT EXISTS log_by_session ON log (session, name, time);
"""


def _storable(value: Any) -> Any:
    # SQLite stores numbers and text; anything else (a NumPy scalar) as its float or text.
    if value is None or isinstance(value, int | float | str | bytes):
        return value
    try:
        return float(value)
    except (TypeError, ValueError):
        return str(value)


class TagDB:
    """Tag values by session in an SQLite database.

    Parameters
    ----------
    filename : str or path
        The database: ``":memory:"`` (the default) or a file, created if missing.

    Attributes
    ----------
    session : int or None
        The session being recorded (``None`` until the first one).

    Raises
    ------
    ValueError
        If the file cannot be opened or is not such a database.

    Examples
    --------
    >>> db = TagDB()
    >>> db.record(0.0, "T1", 21.5); db.record(1.0, "T1", 22.0)
    >>> db.get("T1")
    [(0.0, 21.5), (1.0, 22.0)]
    >>> [(i, n) for i, _, n in db.get_sessions()]
    [(1, 2)]
    """

    def __init__(self, filename: str | Path = ":memory:") -> None:
        self.filename = str(filename)
        try:
            self.db = sqlite3.connect(self.filename, check_same_thread=False)
            self.db.executescript(_SCHEMA)
        except sqlite3.Error as exc:
            raise ValueError(f"cannot log to {self.filename!r}: {exc}") from None
        self.session: int | None = None

    def new_session(self, columns: Sequence[str] = ()) -> None:
        """Start a session (``columns``: the historian's, kept for :meth:`columns`)."""
        started = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
        with self.db:
            cursor = self.db.execute(
                "INSERT INTO sessions (started, columns) VALUES (?, ?)",
                (started, json.dumps(list(columns))),
            )
        assert cursor.lastrowid is not None
        self.session = int(cursor.lastrowid)

    def get_sessions(self) -> list[tuple[int, str, int]]:
        """Every session, oldest first: ``(id, started, distinct times recorded)``."""
        return [
            (int(i), str(started), int(count))
            for i, started, count in self.db.execute(
                "SELECT s.id, s.started, COUNT(DISTINCT l.time) FROM sessions s "
                "LEFT JOIN log l ON l.session = s.id GROUP BY s.id ORDER BY s.id"
            )
        ]

    def columns(self, session: int) -> list[str] | None:
        """The columns a session was started with (``None``: no such session)."""
        found = self.db.execute("SELECT columns FROM sessions WHERE id = ?", (session,)).fetchone()
        return None if found is None else list(json.loads(found[0]))

    def delete_session(self, session_id: int) -> None:
        """Delete a session and its values."""
        with self.db:
            self.db.execute("DELETE FROM log WHERE session = ?", (session_id,))
            self.db.execute("DELETE FROM sessions WHERE id = ?", (session_id,))

    def record(self, timeseconds: float, name: str, value: Any) -> None:
        """Record tag ``name`` = ``value`` at ``timeseconds`` (a session is started if none)."""
        self.record_row(timeseconds, {name: value})

    def record_row(self, timeseconds: float, values: Mapping[str, Any]) -> None:
        """Record several tags at one time, in one transaction."""
        if self.session is None:
            self.new_session()
        with self.db:
            self.db.executemany(
                "INSERT INTO log (session, time, name, value) VALUES (?, ?, ?, ?)",
                [(self.session, timeseconds, n, _storable(v)) for n, v in values.items()],
            )

    def get(
        self, name: str, timeseconds: float | None = None, session: int | None = None
    ) -> list[tuple[float, Any]]:
        """``(time, value)`` of tag ``name`` in ``session`` (default: the current), by time."""
        query = "SELECT time, value FROM log WHERE session = ? AND name = ?"
        parameters: list[Any] = [self.session if session is None else session, name]
        if timeseconds is not None:
            query += " AND time = ?"
            parameters.append(timeseconds)
        return [
            (t, math.nan if v is None else v)
            for t, v in self.db.execute(query + " ORDER BY time, rowid", parameters)
        ]

    def rows(self, session: int) -> dict[float, dict[str, Any]]:
        """A session's values by time, then by tag name."""
        rows: dict[float, dict[str, Any]] = {}
        for t, name, value in self.db.execute(
            "SELECT time, name, value FROM log WHERE session = ? ORDER BY time, rowid", (session,)
        ):
            rows.setdefault(t, {})[str(name)] = math.nan if value is None else value
        return rows

    def clean(self) -> None:
        """Delete the sessions that recorded nothing."""
        with self.db:
            self.db.execute("DELETE FROM sessions WHERE id NOT IN (SELECT session FROM log)")

    def close(self) -> None:
        """Delete the empty sessions and close the database."""
        self.clean()
        self.db.close()
