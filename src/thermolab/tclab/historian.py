"""The ``tclab`` package's ``Historian``: a log of named sources, sampled on demand.

``Historian(sources)`` takes ``(name, function)`` pairs (``lab.sources``
gives the connected rig's) and derives its columns from them, the way
ThermoLab's records derive theirs from named channels.
"""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from thermolab.tclab.labtime import labtime

__all__ = ["Historian", "Source"]

Source = tuple[str, Callable[[], Any]]


class Historian:
    """Record ``Time`` and every source at each :meth:`update`.

    Parameters
    ----------
    sources : sequence of (name, callable)
        What to record; each callable returns the current value.
    dbfile : None
        Only ``None``: the log is kept in memory (:meth:`to_csv` writes it).

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

    def __init__(self, sources: Sequence[Source], dbfile: str | None = None) -> None:
        if dbfile is not None:
            raise ValueError(
                "Historian(dbfile=...) is not supported by thermolab.tclab: the log stays in "
                "memory; write it with Historian.to_csv(path) (the lab also keeps every run)"
            )
        names = [name for name, _ in sources]
        if len(set(names)) != len(names) or "Time" in names:
            raise ValueError(f"source names must be distinct and not 'Time'; got {names}")
        self.sources = list(sources)
        self.columns = ["Time", *names]
        self.log: list[tuple[float, ...]] = []
        self._start = labtime.time()

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
        when = labtime.time() - self._start if tnow is None else float(tnow)
        self.log.append((when, *(float(function()) for _, function in self.sources)))

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
