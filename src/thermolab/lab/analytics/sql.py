"""SQL that SQLite and PostgreSQL spell differently, written once for both.

Instants are :class:`~thermolab.lab.db.models.UTCDateTime` columns: naive UTC
text on SQLite, ``timestamptz`` on PostgreSQL. :func:`seconds_between` turns
two of them into a number of seconds in the database (``julianday`` on
SQLite, ``EXTRACT(EPOCH ...)`` on PostgreSQL); :func:`later` and
:func:`earlier` are ``GREATEST``/``LEAST`` (SQLite's many-argument ``max``
and ``min``); :func:`percentile` is a linear-interpolation percentile (as
PostgreSQL's ``percentile_cont`` and NumPy's default) built from window
functions, which SQLite lacks as an aggregate.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BindParameter,
    ColumnElement,
    Float,
    Select,
    SQLColumnExpression,
    bindparam,
    case,
    func,
    select,
)
from sqlalchemy.ext.compiler import compiles
from sqlalchemy.sql.compiler import SQLCompiler
from sqlalchemy.sql.expression import FunctionElement

from thermolab.lab.db.models import UTCDateTime

__all__ = [
    "SECONDS_DECIMALS",
    "at",
    "clipped_seconds",
    "earlier",
    "json_document",
    "later",
    "percentile",
    "seconds",
    "seconds_between",
]


#: Seconds are given to the millisecond: SQLite's julianday arithmetic is exact to ~50 µs.
SECONDS_DECIMALS = 3


def seconds(value: object) -> float:
    """A number of seconds the database computed, rounded to :data:`SECONDS_DECIMALS`."""
    return round(float(value or 0.0), SECONDS_DECIMALS)  # type: ignore[arg-type]


def at(name: str, value: datetime) -> BindParameter[datetime]:
    """A bound instant, stored like the columns it is compared with."""
    return bindparam(name, value, type_=UTCDateTime, unique=True)


class seconds_between(FunctionElement[float]):  # noqa: N801 - used like func.*
    """``end - start`` in seconds (a float), for two instants."""

    type = Float()
    inherit_cache = True
    name = "seconds_between"


@compiles(seconds_between, "sqlite")
def _seconds_sqlite(element: seconds_between, compiler: SQLCompiler, **kw: Any) -> str:
    start, end = list(element.clauses)
    return (
        f"((julianday({compiler.process(end, **kw)}) - "
        f"julianday({compiler.process(start, **kw)})) * 86400.0)"
    )


@compiles(seconds_between)
def _seconds_default(element: seconds_between, compiler: SQLCompiler, **kw: Any) -> str:
    start, end = list(element.clauses)
    return f"EXTRACT(EPOCH FROM ({compiler.process(end, **kw)} - {compiler.process(start, **kw)}))"


class json_document(FunctionElement[Any]):  # noqa: N801
    """A JSON column parsed once, to read several fields of it.

    PostgreSQL's ``json`` is text, parsed again at every ``->``; cast to
    ``jsonb`` (in a subquery the planner keeps, e.g. with ``OFFSET 0``) it is
    parsed once and each field read from the binary form. SQLite's JSON
    functions take the text as it is.
    """

    type = JSON()
    inherit_cache = True
    name = "json_document"


@compiles(json_document)
def _document_default(element: json_document, compiler: SQLCompiler, **kw: Any) -> str:
    return str(compiler.process(element.clauses, **kw))


@compiles(json_document, "postgresql")
def _document_postgresql(element: json_document, compiler: SQLCompiler, **kw: Any) -> str:
    return f"CAST({compiler.process(element.clauses, **kw)} AS JSONB)"


class later(FunctionElement[datetime]):  # noqa: N801
    """The later of two instants (``GREATEST``)."""

    type = UTCDateTime()
    inherit_cache = True
    name = "later"


class earlier(FunctionElement[datetime]):  # noqa: N801
    """The earlier of two instants (``LEAST``)."""

    type = UTCDateTime()
    inherit_cache = True
    name = "earlier"


@compiles(later, "sqlite")
def _later_sqlite(element: later, compiler: SQLCompiler, **kw: Any) -> str:
    return f"max({compiler.process(element.clauses, **kw)})"


@compiles(later)
def _later_default(element: later, compiler: SQLCompiler, **kw: Any) -> str:
    return f"GREATEST({compiler.process(element.clauses, **kw)})"


@compiles(earlier, "sqlite")
def _earlier_sqlite(element: earlier, compiler: SQLCompiler, **kw: Any) -> str:
    return f"min({compiler.process(element.clauses, **kw)})"


@compiles(earlier)
def _earlier_default(element: earlier, compiler: SQLCompiler, **kw: Any) -> str:
    return f"LEAST({compiler.process(element.clauses, **kw)})"


def clipped_seconds(
    start: SQLColumnExpression[datetime],
    end: SQLColumnExpression[datetime],
    window_from: datetime,
    window_to: datetime,
) -> ColumnElement[float]:
    """Seconds of ``[start, end)`` inside ``[window_from, window_to)`` (overlapping spans only)."""
    return seconds_between(
        later(start, at("window_from", window_from)), earlier(end, at("window_to", window_to))
    )


def percentile(
    values: Select[Any, Any], key: str, value: str, fractions: dict[str, tuple[int, int]]
) -> Select[Any, Any, Any, Any]:
    """Per ``key``: the count of ``value`` and each percentile, linearly interpolated.

    ``values`` selects the columns ``key`` and ``value``; ``fractions`` names
    each percentile as ``num/den`` (``{"median": (1, 2), "p90": (9, 10)}``),
    integers so that the rank arithmetic is exact on both databases. The
    percentile at rank ``r = (n - 1) * num / den`` (0-based, over the sorted
    values) is ``v[floor(r)] + frac(r) * (v[floor(r) + 1] - v[floor(r)])``.
    """
    inner = values.subquery("vals")
    k, v = inner.c[key], inner.c[value]
    ranked = select(
        k.label("key"),
        v.label("value"),
        (func.row_number().over(partition_by=k, order_by=v) - 1).label("i"),
        func.count().over(partition_by=k).label("n"),
    ).subquery("ranked")
    columns: list[ColumnElement[Any]] = [ranked.c.key, func.max(ranked.c.n).label("count")]
    for name, (num, den) in fractions.items():
        scaled = (ranked.c.n - 1) * num
        low = scaled // den
        frac = (scaled % den) * 1.0 / den
        weight = case((ranked.c.i == low, 1.0 - frac), (ranked.c.i == low + 1, frac), else_=0.0)
        columns.append(func.sum(ranked.c.value * weight).label(name))
    return select(*columns).group_by(ranked.c.key)
