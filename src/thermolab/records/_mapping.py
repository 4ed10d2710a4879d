"""Which columns are t, u and y, and in which units: the user's file as it comes.

A header cell may carry its unit (``T1 (°C)``, ``Time [s]``); a column map
(``t=Time,u=Q1,y=T1``, by name or by 1-based position) picks the three channels
from any header, or from a file without one; a few layouts are known without a
map (the ``tclab`` Historian's ``Time,T1,T2,Q1,Q2``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

from thermolab.errors import RecordFormatError

__all__ = ["KNOWN_LAYOUTS", "map_columns", "normal_unit", "parse_assignments", "split_unit"]

_UNIT = re.compile(r"^(?P<name>.*?)\s*[\(\[]\s*(?P<unit>[^\)\]]*?)\s*[\)\]]\s*$")
_UNITS = {
    "degc": "°C", "deg c": "°C", "°c": "°C", "ºc": "°C", "celsius": "°C", "c": "°C",
    "degf": "°F", "deg f": "°F", "°f": "°F", "f": "°F",
    "k": "K", "kelvin": "K",
    "s": "s", "sec": "s", "secs": "s", "second": "s", "seconds": "s",
    "%": "%", "pct": "%", "percent": "%",
    "v": "V", "volt": "V", "volts": "V",
}  # fmt: skip

KNOWN_LAYOUTS: tuple[tuple[dict[str, str], dict[str, str]], ...] = (
    # The tclab Historian (Time, T1, T2, Q1, Q2) and Kantor's notebooks: heater 1.
    ({"t": "time", "u": "q1", "y": "t1"}, {"t": "s", "u": "%", "y": "°C"}),
)
"""Column maps recognised without options: (map, units), tried in order."""


def normal_unit(unit: str) -> str:
    """A unit as people write it, in one spelling: ``degC`` -> ``°C``, ``sec`` -> ``s``."""
    return _UNITS.get(unit.strip().lower(), unit.strip())


def split_unit(cell: str) -> tuple[str, str]:
    """``"T1 (°C)"`` -> ``("T1", "°C")``; a cell without a unit -> ``(cell, "")``.

    Examples
    --------
    >>> split_unit(" Temperature 1 (degC)"), split_unit("Time [s]"), split_unit("Q1")
    (('Temperature 1', '°C'), ('Time', 's'), ('Q1', ''))
    """
    m = _UNIT.match(cell.strip())
    if m is None or not m.group("name"):
        return cell.strip(), ""
    return m.group("name").strip(), normal_unit(m.group("unit"))


def parse_assignments(text: str, what: str) -> dict[str, str]:
    """``"t=Time,u=Q1,y=T1"`` -> ``{"t": "Time", "u": "Q1", "y": "T1"}`` (keys t, u, y).

    Raises
    ------
    RecordFormatError
        For a part without ``=``, a key other than t, u, y, or a key given twice.

    Examples
    --------
    >>> parse_assignments("t=1, u=Q1,y=T1 (°C)", "--columns")
    {'t': '1', 'u': 'Q1', 'y': 'T1 (°C)'}
    """
    out: dict[str, str] = {}
    for part in text.split(","):
        key, eq, value = part.partition("=")
        key, value = key.strip().lower(), value.strip()
        if not eq or key not in ("t", "u", "y") or not value:
            raise RecordFormatError(
                f"{what}: {part.strip()!r} is not KEY=VALUE with KEY one of t, u, y "
                f"(e.g. {what} t=Time,u=Q1,y=T1)"
            )
        if key in out:
            raise RecordFormatError(f"{what}: {key} is given twice")
        out[key] = value
    return out


def map_columns(
    path: Path,
    line: int,
    cells: list[str] | None,
    width: int,
    columns: Mapping[str, str | int],
) -> dict[str, int]:
    """The 0-based column of each of ``t, u, y`` in a header (or a file without one).

    ``columns`` maps t, u, y to a header name (with or without its unit, any
    case) or a 1-based position (an int, or digits).
    """
    missing = [k for k in ("t", "u", "y") if k not in columns]
    if missing:
        raise RecordFormatError(
            f"{path}: the column map lacks {', '.join(missing)}; it needs t, u and y "
            "(e.g. t=Time,u=Q1,y=T1 or t=1,u=2,y=3)"
        )
    out: dict[str, int] = {}
    for key in ("t", "u", "y"):
        target = columns[key]
        text = str(target).strip()
        if isinstance(target, int) or text.isdigit():
            j = int(text) - 1
            if not 0 <= j < width:
                raise RecordFormatError(
                    f"{path}: column {key}={text}: the file has {width} columns "
                    "(positions count from 1)"
                )
        else:
            if cells is None:
                raise RecordFormatError(
                    f"{path}: column {key}={text!r}: the file has no header (line {line} holds "
                    "numbers); give positions instead, e.g. t=1,u=2,y=3"
                )
            wanted = text.lower()
            found = [
                j
                for j, c in enumerate(cells)
                if c.strip().lower() == wanted or split_unit(c)[0].lower() == wanted
            ]
            if len(found) != 1:
                shown = ",".join(c.strip() for c in cells)
                why = "names no such column" if not found else "names it more than once"
                raise RecordFormatError(
                    f"{path}: column {key}={text!r}: the header (line {line}) {why} "
                    f"(got {shown[:80]!r})"
                )
            j = found[0]
        out[key] = j
    if len(set(out.values())) < 3:
        raise RecordFormatError(f"{path}: the column map gives one column two roles: {columns}")
    return out
