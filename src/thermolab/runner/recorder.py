"""Incremental sample records: every sample reaches the file as soon as it is taken.

:class:`CsvRecorder` writes one row per sample through
:class:`thermolab.records.RecordWriter` and flushes it to the operating
system at once, so a crash of the process loses at most the sample being
taken (at most one sample period of data); with ``fsync=True`` every row is
also forced to the disk, which protects against a power cut as well at the
price of one disk sync per sample (worth it at 1 Hz on real hardware, not in
a simulated run of 20,000 samples per second).

The columns are the run's channels (:data:`thermolab.records.RUN_CHANNELS`:
``t,u,y`` first, so that the file feeds straight into ``thermolab identify``,
then the sample index, the time of the reading, the jitter and the lateness;
then any extra channels the run declares). The record format itself (floats
as the shortest text that reads back to the same double, ``t`` to 12
significant digits) is :mod:`thermolab.records`'.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol, TextIO, runtime_checkable

from thermolab.errors import InvalidParameterError
from thermolab.records import RUN_CHANNELS, ChannelSpec, RecordWriter, channel_names

__all__ = ["CSV_COLUMNS", "CsvRecorder", "Recorder"]

CSV_COLUMNS: tuple[str, ...] = channel_names(RUN_CHANNELS)
"""Column order of a run's CSV record without extra channels."""


@runtime_checkable
class Recorder(Protocol):
    """Where a run writes its samples, one at a time.

    ``open`` is called at START, ``write`` once per sample in order, ``close``
    on every way out (also after an error). A recorder that raises stops the
    run (FAULTED, actuator safe). A recorder for a run with extra channels
    (``Experiment(sources=...)``) has a ``channels`` attribute equal to the
    run's and takes their values after the seven standard ones.
    """

    def open(self) -> None:
        """Prepare to receive samples (create the file, write a header)."""
        ...

    def write(
        self, k: int, t: float, u: float, y: float, t_read: float, jitter: float, lateness: float
    ) -> None:
        """Record one sample (see :class:`~thermolab.runner.SampleEvent` for the fields)."""
        ...

    def close(self) -> None:
        """Make everything durable and release resources (idempotent)."""
        ...


class CsvRecorder:
    """Write samples to a CSV file, one flushed row per sample.

    Parameters
    ----------
    path : str or os.PathLike
        The file to create (an existing file is replaced; its folder must exist).
    fsync : bool, optional
        Also force each row to the disk (default ``False``: flushed to the
        operating system only, which survives a crash of the process).
    channels : sequence of ChannelSpec, optional
        The columns (default :data:`~thermolab.records.RUN_CHANNELS`; a run
        with extra channels passes ``Experiment.channels``).
    comments : sequence of str, optional
        Lines written as ``# ...`` before the header (the rig, the signal).

    Raises
    ------
    InvalidParameterError
        If the channels do not start with ``RUN_CHANNELS``; from :meth:`open`,
        if the file cannot be created.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "run.csv"
    >>> rec = CsvRecorder(path)
    >>> rec.open()
    >>> rec.write(0, 0.0, 5.0, 0.25, 0.0, 0.0, 0.0)
    >>> path.read_text().splitlines()  # readable before close()
    ['t,u,y,k,t_read,jitter,lateness', '0,5.0,0.25,0,0.0,0.0,0.0']
    >>> rec.close()
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        fsync: bool = False,
        channels: Sequence[ChannelSpec] = RUN_CHANNELS,
        comments: Sequence[str] = (),
    ) -> None:
        channels = tuple(channels)
        if channels[: len(RUN_CHANNELS)] != RUN_CHANNELS:
            raise InvalidParameterError(
                f"a run's record starts with the channels {','.join(CSV_COLUMNS)}; "
                f"got {','.join(channel_names(channels))}"
            )
        self.path = Path(path)
        self.fsync = fsync
        self.channels = channels
        self.comments = tuple(comments)
        self._file: TextIO | None = None
        self._writer: RecordWriter | None = None

    @property
    def rows(self) -> int:
        """Rows written so far."""
        return 0 if self._writer is None else self._writer.rows

    def open(self) -> None:
        """Create the file and write the header line.

        Raises
        ------
        InvalidParameterError
            If the file cannot be created (missing folder, no permission).
        """
        try:
            # newline="" keeps the CSV line ends exactly "\n" on every platform.
            self._file = self.path.open("w", encoding="utf-8", newline="")
        except OSError as exc:
            raise InvalidParameterError(
                f"cannot write the record {str(self.path)!r}: {exc.strerror or exc}"
            ) from None
        self._writer = RecordWriter(self._file, self.channels, comments=self.comments)
        self._writer.write_header()
        self._flush()

    def write(
        self,
        k: int,
        t: float,
        u: float,
        y: float,
        t_read: float,
        jitter: float,
        lateness: float,
        *extra: float,
    ) -> None:
        """Append one row and flush it.

        Parameters
        ----------
        k, t, u, y, t_read, jitter, lateness
            The sample (see :data:`CSV_COLUMNS`).
        *extra
            The values of the extra channels, in channel order.

        Raises
        ------
        RuntimeError
            If the recorder is not open.
        InvalidParameterError
            If the number of values is not the number of channels.
        OSError
            If the disk refuses the write (disk full): the run stops.
        """
        writer = self._writer
        if writer is None or self._file is None:
            raise RuntimeError(f"CsvRecorder({str(self.path)!r}) is not open")
        writer.write_row((t, u, y, k, t_read, jitter, lateness, *extra))
        self._flush()

    def close(self) -> None:
        """Flush (and sync) the file and close it (idempotent)."""
        file, self._file = self._file, None
        if file is None:
            return
        try:
            file.flush()
            os.fsync(file.fileno())
        finally:
            file.close()

    def _flush(self) -> None:
        assert self._file is not None
        self._file.flush()
        if self.fsync:
            os.fsync(self._file.fileno())

    def __repr__(self) -> str:
        return f"CsvRecorder({str(self.path)!r}, rows={self.rows})"
