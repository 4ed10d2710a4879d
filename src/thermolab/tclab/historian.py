"""The ``tclab`` package's ``Historian``: a log of named sources, sampled on demand.

``Historian(sources)`` takes ``(name, function)`` pairs (``lab.sources``
gives a kit's: ``T1``, ``T2``, ``Q1``, ``Q2`` from one ``scan``) and derives
its columns from them: ``Time`` first, then the names. A function may give
several values at once (a tuple): the names after it, paired with ``None``,
take the next values, so one call reads several channels.

As in the ``tclab`` package every historian logs to an SQLite database
(a :class:`~thermolab.tclab.tagdb.TagDB`) — in memory by default
(``dbfile=":memory:"``), or a file, so a notebook that crashed, or a later
one, finds its data. Each historian (and each :meth:`Historian.new_session`)
is a new *session*; :meth:`Historian.get_sessions` lists them and
:meth:`Historian.load_session` reads one back (rows by time: two updates at
the same time come back as one, as in ``tclab``). ``dbfile=None`` keeps the
log in memory without sessions.
"""

from __future__ import annotations

import bisect
import csv
import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

from thermolab.tclab.labtime import labtime
from thermolab.tclab.tagdb import TagDB

__all__ = ["Historian", "NoDatabaseError", "Source", "TagDB"]

Source = tuple[str, Callable[[], Any] | None]
"""A column's name and the function that gives its value (``None``: the previous one's next)."""


class NoDatabaseError(NotImplementedError):
    """Sessions need the historian's database (``dbfile``); this one has none, or closed it.

    A ``NotImplementedError``, as tclab's ``Historian`` raises in the same case
    ("Sessions not supported without dbfile"): a notebook's ``except`` still catches it.
    """


class Historian:
    """Record ``Time`` and every source at each :meth:`update`.

    Parameters
    ----------
    sources : iterable of (name, callable or None)
        What to record; each callable returns the current value, or several
        values for itself and the names after it that come with ``None``.
    dbfile : str or path or None
        The SQLite database that receives every row, in a new session:
        ``":memory:"`` (the default, as in the ``tclab`` package), a file
        (created if missing), or ``None`` for no database (no sessions).

    Attributes
    ----------
    columns : list of str
        ``"Time"`` and the sources' names.
    fields : list of lists
        Each column's values, in column order (``t, T1, T2, Q1, Q2 = h.fields``).
    logdict : dict of lists
        The same lists by column name.
    t : list
        The times (``logdict["Time"]``).
    tnow : float
        The time of the last update, in lab seconds since the session began.
    session : int
        The session being logged (1 without a database).

    Examples
    --------
    >>> values = iter([20.0, 21.5])
    >>> h = Historian([("T1", lambda: next(values))])
    >>> h.update(0.0); h.update(1.0)
    >>> h.columns, h.log
    (['Time', 'T1'], [(0.0, 20.0), (1.0, 21.5)])
    >>> h.at(0.5)
    [0.0, 20.0]
    >>> h.after(1.0)
    [[1.0], [21.5]]
    """

    def __init__(self, sources: Iterable[Source], dbfile: str | Path | None = ":memory:") -> None:
        self.sources = list(sources)
        names = [name for name, _ in self.sources]
        if len(set(names)) != len(names) or "Time" in names:
            raise ValueError(f"source names must be distinct and not 'Time'; got {names}")
        if self.sources and self.sources[0][1] is None:
            raise ValueError(
                f"the first source ({names[0]!r}) needs a function: None means "
                "'the next value of the function before'"
            )
        self.columns = ["Time", *names]
        self.dbfile = None if not dbfile else str(dbfile)
        self.session = 1
        self.tnow = 0.0
        self.db: TagDB | None = None
        """The database (``None`` without one, or once closed)."""
        if self.dbfile is not None:
            self.db = TagDB(self.dbfile)
            self.db.new_session(self.columns)
            assert self.db.session is not None
            self.session = self.db.session
        self.tstart = labtime.time()
        self._build_fields(self.columns)

    def _build_fields(self, columns: list[str]) -> None:
        self.columns = columns
        self.fields: list[list[Any]] = [[] for _ in columns]
        self.logdict: dict[str, list[Any]] = dict(zip(columns, self.fields, strict=True))
        self.t: list[Any] = self.logdict["Time"]

    def _database(self, what: str) -> TagDB:
        if self.db is None:
            state = "closed its database" if self.dbfile is not None else "has no database"
            raise NoDatabaseError(
                f"{what} needs the historian's database, and this historian {state} "
                "(Historian(sources, dbfile=':memory:' or a file) keeps sessions)"
            )
        return self.db

    # -- sessions ---------------------------------------------------------------------------

    def new_session(self) -> None:
        """Start a new session: an empty log, time from 0 again, a new id in the database.

        Raises
        ------
        NoDatabaseError
            Without a database (``dbfile=None``).
        """
        db = self._database("new_session")
        self._build_fields(["Time", *(name for name, _ in self.sources)])
        db.new_session(self.columns)
        assert db.session is not None
        self.session = db.session
        self.tstart = labtime.time()

    def get_sessions(self) -> list[tuple[int, str, int]]:
        """The database's sessions, oldest first: ``(id, started, rows logged)``.

        Raises
        ------
        NoDatabaseError
            Without a database.
        """
        return self._database("get_sessions").get_sessions()

    def load_session(self, session: int) -> None:
        """Replace the log (and its columns) with a stored session's rows.

        Logging goes on into that session. Its columns must be this
        historian's sources' to log more; reading only needs the session.

        Raises
        ------
        NoDatabaseError
            Without a database.
        ValueError
            If the database has no such session.
        """
        db = self._database("load_session")
        columns = db.columns(session)
        if columns is None:
            ids = [s[0] for s in db.get_sessions()]
            raise ValueError(f"no session {session!r} in {self.dbfile!r}; sessions: {ids}")
        self._build_fields(columns)
        for t, values in db.rows(session).items():
            self.t.append(t)
            for name, column in zip(self.columns[1:], self.fields[1:], strict=True):
                column.append(values.get(name, math.nan))
        db.session = self.session = int(session)
        self.tnow = self.t[-1] if self.t else 0.0
        self.tstart = labtime.time() - self.tnow

    def close(self) -> None:
        """Close the database (its empty sessions deleted); the log in memory stays readable."""
        if self.db is not None:
            self.db.close()
            self.db = None

    # -- logging ----------------------------------------------------------------------------

    def _values(self) -> list[Any]:
        # Values a function gives beyond its names are ignored, as in the ``tclab`` package.
        values: list[Any] = []
        pending: Iterator[Any] | None = None
        group: list[str] = []
        for name, function in self.sources:
            if function is not None:
                result = function()
                if isinstance(result, str | bytes) or not hasattr(result, "__iter__"):
                    result = (result,)
                pending, group = iter(result), []
            group.append(name)
            assert pending is not None
            try:
                values.append(next(pending))
            except StopIteration:
                raise ValueError(
                    f"the source of {group[0]!r} gave {len(group) - 1} value(s) for "
                    f"{len(group)} names ({', '.join(group)})"
                ) from None
        return values

    def update(self, tnow: float | None = None) -> None:
        """Append a row: ``tnow`` (default: lab seconds since the session began) and each source.

        Raises
        ------
        ValueError
            If a multi-value source gives fewer values than its names, or the
            loaded session has other columns than the sources.
        """
        if self.columns != ["Time", *(name for name, _ in self.sources)]:
            raise ValueError(
                f"session {self.session} logs {self.columns}, not this historian's sources"
            )
        self.tnow = labtime.time() - self.tstart if tnow is None else tnow
        row = [self.tnow, *self._values()]
        if self.db is not None:
            self.db.record_row(self.tnow, dict(zip(self.columns[1:], row[1:], strict=True)))
        for column, value in zip(self.fields, row, strict=True):
            column.append(value)

    # -- reading ----------------------------------------------------------------------------

    @property
    def log(self) -> list[tuple[Any, ...]]:
        """The rows, oldest first: ``(Time, *sources)``."""
        return list(zip(*self.fields, strict=True))

    def _columns(self, columns: Sequence[str] | None) -> list[str]:
        wanted = self.columns if columns is None else list(columns)
        unknown = [c for c in wanted if c not in self.logdict]
        if unknown:
            raise KeyError(f"no column {unknown[0]!r}; the columns are {self.columns}")
        return wanted

    def timeindex(self, t: float) -> int:
        """The index of the row in force at time ``t`` (the latest at or before it; 0 before)."""
        return max(bisect.bisect(self.t, t) - 1, 0)

    def timeslice(
        self, tstart: float = 0, tend: float | None = None, columns: Sequence[str] | None = None
    ) -> list[list[Any]]:
        """Each column's values from the row in force at ``tstart`` to the one at ``tend``.

        Raises
        ------
        ValueError
            If nothing was logged yet.
        KeyError
            For a column the historian does not have.
        """
        wanted = self._columns(columns)
        if not self.t:
            raise ValueError("nothing logged yet: update() the historian first")
        start = self.timeindex(tstart)
        stop = len(self.t) if tend is None else max(self.timeindex(tend) + 1, start + 1)
        return [self.logdict[c][start:stop] for c in wanted]

    def at(self, t: float, columns: Sequence[str] | None = None) -> list[Any]:
        """The values of ``columns`` (default: all) at time ``t`` (the row at or just before)."""
        return [values[0] for values in self.timeslice(t, t, columns)]

    def after(self, t: float, columns: Sequence[str] | None = None) -> list[list[Any]]:
        """Each column's values from the row in force at time ``t`` on (columns, as ``fields``)."""
        return self.timeslice(t, None, columns)

    def to_csv(self, filename: str | Path) -> None:
        """Write the log as CSV: a header of the column names, then one row per update."""
        with open(filename, "w", newline="", encoding="utf-8") as stream:
            writer = csv.writer(stream)
            writer.writerow(self.columns)
            writer.writerows(self.log)
