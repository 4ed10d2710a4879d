"""A stored run read back by channel: the CSV and JSON exports.

:meth:`RunExport.channels` gives a run's channel specs (those stored with it,
or for older runs what its samples hold), :meth:`RunExport.channel_rows`
each sample's values of them, and :func:`samples_csv` writes them with
:mod:`thermolab.records`, the one record format.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterable, Iterator, Sequence
from typing import Any

from sqlalchemy import ColumnElement, select

from thermolab.jsonsafe import json_safe
from thermolab.lab.db import Database
from thermolab.lab.db.models import Run, Sample
from thermolab.lab.runs.store import channel_specs
from thermolab.lab.spreadsheets import SheetDialect
from thermolab.records import RUN_CHANNELS, ChannelSpec, RecordWriter, unit_symbol

__all__ = ["RunExport", "StoredSample", "StoredSampleWithExtra", "samples_csv"]

StoredSample = tuple[int, float, float, float]
"""``(k, t, u, y)`` of a stored sample."""
StoredSampleWithExtra = tuple[int, float, float, float, dict[str, float | None] | None]
"""``(k, t, u, y, extra)`` of a stored sample: ``extra`` its further channels by name (or None)."""

#: The channels of a sample stored before revision 0004 (no timing, no extras).
_EARLY_CHANNELS: tuple[ChannelSpec, ...] = RUN_CHANNELS[:4]
#: The standard channels, each a column of ``samples``.
_COLUMNS = {c.name: getattr(Sample, c.name) for c in RUN_CHANNELS}


def samples_csv(
    channels: Sequence[ChannelSpec],
    rows: Iterable[Sequence[float]],
    dialect: SheetDialect | None = None,
) -> Iterator[str]:
    r"""The CSV text of a run's record, in chunks, in the one record format.

    Written by :class:`thermolab.records.RecordWriter`. With ``dialect``, the
    spreadsheet form instead: each heading the channel's name and unit
    (``y (V)``), the dialect's separator and decimal mark, 10 significant
    digits; :func:`thermolab.records.read_record` reads that form too.

    Columns ``t,u,y`` first, then the other channels: the file feeds straight
    into ``thermolab identify`` and :func:`thermolab.records.read_record`.

    Examples
    --------
    >>> from thermolab.records import RUN_CHANNELS
    >>> "".join(samples_csv(RUN_CHANNELS[:4], [(0.0, 1.0, 0.5, 0), (1.0, 1.0, 0.625, 1)]))
    't,u,y,k\n0,1.0,0.5,0\n1,1.0,0.625,1\n'
    """
    if dialect is not None:
        yield from _samples_sheet(channels, rows, dialect)
        return
    buffer = io.StringIO()
    writer = RecordWriter(buffer, channels)
    writer.write_header()
    for row in rows:
        writer.write_row(row)
        if writer.rows % 1000 == 0:
            yield buffer.getvalue()
            buffer.seek(0)
            buffer.truncate()
    yield buffer.getvalue()


def _samples_sheet(
    channels: Sequence[ChannelSpec], rows: Iterable[Sequence[float]], dialect: SheetDialect
) -> Iterator[str]:
    header = [f"{c.name} ({unit_symbol(c.unit)})" if c.unit else c.name for c in channels]
    integer = [c.integer for c in channels]

    def cells(row: Sequence[float]) -> list[float | int]:
        return [
            int(v) if whole and math.isfinite(v) else v
            for v, whole in zip(row, integer, strict=True)
        ]

    return dialect.lines(header, (cells(row) for row in rows))


class RunExport:
    """Reads a run's samples back by channel (ownership is checked by the caller)."""

    def __init__(self, db: Database) -> None:
        self._db = db

    def samples(self, run_id: int) -> Iterator[StoredSample]:
        """Yield ``(k, t, u, y)`` of every stored sample of a run, in order."""
        with self._db.read() as session:
            rows = session.execute(
                select(Sample.k, Sample.t, Sample.u, Sample.y)
                .where(Sample.run_id == run_id)
                .order_by(Sample.k)
                .execution_options(yield_per=2000)
            )
            for row in rows:
                yield (row[0], row[1], row[2], row[3])

    def sample_page(
        self, run_id: int, after: int | None, limit: int, upto: int | None = None
    ) -> list[StoredSample]:
        """One page of a run's stored samples: up to ``limit`` with ``after < k <= upto``, in order.

        Keyset paging on the primary key ``(run_id, k)``: each page is one
        bounded index range, however long the run (``after=None``: from the first).
        """
        query = (
            select(Sample.k, Sample.t, Sample.u, Sample.y)
            .where(*_page_of(run_id, after, upto))
            .order_by(Sample.k)
            .limit(limit)
        )
        with self._db.read() as session:
            return [(row[0], row[1], row[2], row[3]) for row in session.execute(query)]

    def sample_page_with_extra(
        self, run_id: int, after: int | None, limit: int, upto: int | None = None
    ) -> list[StoredSampleWithExtra]:
        """:meth:`sample_page` with each sample's further channels (its ``extra``) as well."""
        query = (
            select(Sample.k, Sample.t, Sample.u, Sample.y, Sample.extra)
            .where(*_page_of(run_id, after, upto))
            .order_by(Sample.k)
            .limit(limit)
        )
        with self._db.read() as session:
            return [(row[0], row[1], row[2], row[3], row[4]) for row in session.execute(query)]

    def newest_samples(self, run_id: int, count: int) -> tuple[int, int] | None:
        """``(first k, last k)`` of a run's ``count`` newest stored samples (fewer if it has fewer).

        ``None`` when the run has no stored sample. Two index-only lookups.
        """
        newest = select(Sample.k).where(Sample.run_id == run_id).order_by(Sample.k.desc())
        with self._db.read() as session:
            last = session.scalar(newest.limit(1))
            if last is None:
                return None
            first = session.scalar(newest.offset(count - 1).limit(1))
            if first is None:  # fewer than count: all of them
                first = session.scalar(newest.order_by(None).order_by(Sample.k).limit(1))
        assert first is not None
        return first, last

    def channels(self, run_id: int) -> tuple[ChannelSpec, ...]:
        """The channels of a run's stored samples, in record order.

        The specs stored with the run (:func:`add_run`). A run stored before
        the lab kept them: :data:`~thermolab.records.RUN_CHANNELS` and the
        extra channels of the first sample, by name (``t,u,y,k`` for samples
        stored before revision 0004, which have no timing).
        """
        with self._db.read() as session:
            meta = session.scalar(select(Run.meta).where(Run.id == run_id))
            if meta and "channels" in meta:
                return channel_specs(meta["channels"])
            first = session.execute(
                select(Sample.t_read, Sample.extra)
                .where(Sample.run_id == run_id)
                .order_by(Sample.k)
                .limit(1)
            ).first()
        if first is None or first[0] is None:
            return _EARLY_CHANNELS
        return (*RUN_CHANNELS, *(ChannelSpec(name) for name in first[1] or {}))

    def further_channels(self, run_id: int) -> tuple[str, ...]:
        """The names of a run's further channels, those kept in its samples' ``extra``
        (a kit's ``t2`` and ``q2``; none for a one-channel run), in record order."""
        return tuple(c.name for c in self.channels(run_id) if c.name not in _COLUMNS)

    def channel_rows(
        self, run_id: int, channels: Sequence[ChannelSpec]
    ) -> Iterator[tuple[float, ...]]:
        """Yield each stored sample's values of ``channels`` (from :meth:`channels`), in order.

        A value missing from a sample (an extra channel it lacks, a null) is NaN.
        """
        standard = [c.name for c in channels if c.name in _COLUMNS]
        extra = [c.name for c in channels if c.name not in _COLUMNS]
        order = [c.name for c in channels]
        with self._db.read() as session:
            rows = session.execute(
                select(*(_COLUMNS[name] for name in standard), Sample.extra)
                .where(Sample.run_id == run_id)
                .order_by(Sample.k)
                .execution_options(yield_per=2000)
            )
            for row in rows:
                values = dict(zip(standard, row, strict=False))
                stored = row[-1] or {}
                values.update({name: stored.get(name) for name in extra})
                yield tuple(math.nan if values[n] is None else values[n] for n in order)

    def record(self, run_id: int) -> dict[str, Any]:
        """A run's samples by channel, for ``export.json``.

        Returns
        -------
        dict
            ``{"channels": [ChannelSpec.to_dict(), ...], "samples": {name: [value, ...]}}``
            (non-finite values as ``None``), in record order.
        """
        channels = self.channels(run_id)
        columns: list[list[float]] = [[] for _ in channels]
        for row in self.channel_rows(run_id, channels):
            for column, value in zip(columns, row, strict=True):
                column.append(value)
        samples = {c.name: column for c, column in zip(channels, columns, strict=True)}
        for c in channels:
            if c.integer:
                samples[c.name] = [int(v) for v in samples[c.name]]
        return {"channels": [c.to_dict() for c in channels], "samples": json_safe(samples)}


def _page_of(run_id: int, after: int | None, upto: int | None) -> list[ColumnElement[bool]]:
    """The conditions of one keyset page of a run's samples (``after < k <= upto``)."""
    conditions = [Sample.run_id == run_id]
    if after is not None:
        conditions.append(Sample.k > after)
    if upto is not None:
        conditions.append(Sample.k <= upto)
    return conditions
