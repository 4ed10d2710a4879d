"""The ``tclab`` package's ``Historian``: a log of named sources, sampled on demand.

``Historian(sources)`` takes ``(name, function)`` pairs (``lab.sources``
gives the connected rig's) and derives its columns from them, the way
ThermoLab's records derive theirs from named channels.

``Historian(sources, dbfile="log.db")`` also writes every row to an SQLite
file as it is logged, as the kit's package does: each historian (and each
:meth:`Historian.new_session`) is a new *session* in that file;
:meth:`Historian.get_sessions` lists them and :meth:`Historian.load_session`
reads one back into the log — so a notebook that crashed, or a later one,
finds its data. The file's layout is ours (standard-library :mod:`sqlite3`):
``sessions(id, started, columns)`` — ``started`` an ISO 8601 UTC time,
``columns`` a JSON list — and ``log(session, row, name, value)``, one value
per column and row (``Time`` included), easy to query with plain SQL.
"""

from __future__ import annotations

import csv
import datetime
import json
import math
import sqlite3
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from thermolab.tclab.labtime import labtime

__all__ = ["Historian", "Source"]

Source = tuple[str, Callable[[], Any]]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS sessions (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    started TEXT NOT NULL,
    columns TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS log (
    session INTEGER NOT NULL REFERENCES sessions (id),
    row INTEGER NOT NULL,
    name TEXT NOT NULL,
    value REAL,
    PRIMARY KEY (session, row, name)
);
"""


class Historian:
    """Record ``Time`` and every source at each :meth:`update`.

    Parameters
    ----------
    sources : sequence of (name, callable)
        What to record; each callable returns the current value.
    dbfile : str or path, optional
        An SQLite file (created if missing; ``":memory:"`` for a database in
        memory) that receives every row as it is logged, in a new session.
        ``None`` (the default): the log is kept in memory only
        (:meth:`to_csv` writes it).

    Examples
    --------
    >>> values = iter([20.0, 21.5])
    >>> h = Historian([("T1", lambda: next(values))])
    >>> h.update(0.0); h.update(1.0)
    >>> h.columns, h.log
    (['Time', 'T1'], [(0.0, 20.0), (1.0, 21.5)])
    >>> h.at(0.5)
    [0.0, 20.0]
    """

    def __init__(self, sources: Sequence[Source], dbfile: str | Path | None = None) -> None:
        names = [name for name, _ in sources]
        if len(set(names)) != len(names) or "Time" in names:
            raise ValueError(f"source names must be distinct and not 'Time'; got {names}")
        self.sources = list(sources)
        self.columns = ["Time", *names]
        self.log: list[tuple[float, ...]] = []
        self.dbfile = None if dbfile is None else str(dbfile)
        self.session: int | None = None
        self._db: sqlite3.Connection | None = None
        if self.dbfile is not None:
            try:
                self._db = sqlite3.connect(self.dbfile)
                self._db.executescript(_SCHEMA)
            except sqlite3.Error as exc:
                raise ValueError(f"cannot log to {self.dbfile!r}: {exc}") from None
        self.new_session()

    def new_session(self) -> None:
        """Start a new session: an empty log, restarted time, and (with a file) a new id."""
        self.log = []
        self._start = labtime.time()
        if self._db is not None:
            started = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
            with self._db:
                cursor = self._db.execute(
                    "INSERT INTO sessions (started, columns) VALUES (?, ?)",
                    (started, json.dumps(self.columns)),
                )
            self.session = cursor.lastrowid

    def get_sessions(self) -> list[tuple[int, str, int]]:
        """The file's sessions, oldest first: ``(id, started, rows logged)``.

        Raises
        ------
        ValueError
            If the historian has no ``dbfile``.
        """
        db = self._database("get_sessions")
        return [
            (int(i), str(started), int(rows))
            for i, started, rows in db.execute(
                "SELECT s.id, s.started, COUNT(DISTINCT l.row) FROM sessions s "
                "LEFT JOIN log l ON l.session = s.id GROUP BY s.id ORDER BY s.id"
            )
        ]

    def load_session(self, session: int) -> None:
        """Replace the log (and its columns) with a stored session's rows.

        Logging goes on into that session: later updates append to it. Its
        columns must be this historian's sources' to log more; reading only
        needs the session.

        Raises
        ------
        ValueError
            If the historian has no ``dbfile`` or the file has no such session.
        """
        db = self._database("load_session")
        found = db.execute("SELECT columns FROM sessions WHERE id = ?", (session,)).fetchone()
        if found is None:
            ids = [s[0] for s in self.get_sessions()]
            raise ValueError(f"no session {session!r} in {self.dbfile!r}; sessions: {ids}")
        columns = list(json.loads(found[0]))
        rows: dict[int, dict[str, float]] = {}
        for row, name, value in db.execute(
            "SELECT row, name, value FROM log WHERE session = ? ORDER BY row", (session,)
        ):
            # SQLite stores NaN as NULL.
            rows.setdefault(int(row), {})[str(name)] = math.nan if value is None else float(value)
        self.columns = columns
        self.log = [tuple(values.get(c, math.nan) for c in columns) for values in rows.values()]
        self.session = int(session)
        self._start = labtime.time() - (self.log[-1][0] if self.log else 0.0)

    def close(self) -> None:
        """Close the database file (the in-memory log stays readable)."""
        if self._db is not None:
            self._db.close()
            self._db = None

    def _database(self, what: str) -> sqlite3.Connection:
        if self._db is None:
            state = "was closed" if self.dbfile is not None else "has no dbfile"
            raise ValueError(f"{what} needs the historian's database, and this historian {state}")
        return self._db

    @property
    def logdict(self) -> dict[str, list[float]]:
        """Each column's values, by name."""
        return {name: [row[i] for row in self.log] for i, name in enumerate(self.columns)}

    @property
    def fields(self) -> list[list[float]]:
        """Each column's values, in column order."""
        return [[row[i] for row in self.log] for i in range(len(self.columns))]

    @property
    def t(self) -> list[float]:
        """The times of the log."""
        return [row[0] for row in self.log]

    def update(self, tnow: float | None = None) -> None:
        """Append a row: ``tnow`` (default: lab time since the historian began) and each source."""
        if self.columns != ["Time", *(name for name, _ in self.sources)]:
            raise ValueError(
                f"session {self.session} logs {self.columns}, not this historian's sources"
            )
        when = labtime.time() - self._start if tnow is None else float(tnow)
        row = (when, *(float(function()) for _, function in self.sources))
        if self._db is not None:
            with self._db:
                self._db.executemany(
                    "INSERT INTO log (session, row, name, value) VALUES (?, ?, ?, ?)",
                    [
                        (self.session, len(self.log), c, v)
                        for c, v in zip(self.columns, row, strict=True)
                    ],
                )
        self.log.append(row)

    def _pick(self, row: tuple[float, ...], columns: Sequence[str] | None) -> list[float]:
        wanted = self.columns if columns is None else list(columns)
        unknown = [c for c in wanted if c not in self.columns]
        if unknown:
            raise KeyError(f"no column {unknown[0]!r}; the columns are {self.columns}")
        return [row[self.columns.index(c)] for c in wanted]

    def at(self, t: float, columns: Sequence[str] | None = None) -> list[float]:
        """The row in force at time ``t`` (the latest at or before it)."""
        before = [row for row in self.log if row[0] <= t]
        if not before:
            raise ValueError(f"nothing logged at or before t = {t}")
        return self._pick(before[-1], columns)

    def after(self, t: float, columns: Sequence[str] | None = None) -> list[list[float]]:
        """Every row from time ``t`` on."""
        return [self._pick(row, columns) for row in self.log if row[0] >= t]

    def to_csv(self, filename: str | Path) -> None:
        """Write the log as CSV (a header of the column names, then one row per update)."""
        with open(filename, "w", newline="", encoding="utf-8") as stream:
            writer = csv.writer(stream)
            writer.writerow(self.columns)
            writer.writerows(self.log)
