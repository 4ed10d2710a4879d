"""Writing records: a header of channel names and one line per sample."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TextIO

from thermolab.errors import InvalidParameterError
from thermolab.records.channels import ChannelSpec, channel_names, checked_channels

__all__ = ["RecordWriter", "write_record"]


def _template(channels: Sequence[ChannelSpec]) -> str:
    # One str.format call per row: the runner pays a single C call per sample.
    parts = []
    for c in channels:
        if c.integer:
            parts.append("{:.0f}")
        elif c.digits is not None:
            parts.append(f"{{:.{c.digits}g}}")
        else:
            parts.append("{!r}")
    return ",".join(parts) + "\n"


class RecordWriter:
    """Write a record to a text stream, one row at a time.

    Parameters
    ----------
    stream : TextIO
        Where to write (opened with ``newline=""`` for exact ``\\n`` line ends).
    channels : sequence of ChannelSpec
        The columns, starting with ``t, u, y`` (e.g. :data:`RUN_CHANNELS`).
    comments : iterable of str, optional
        Lines written before the header, each prefixed with ``"# "``.

    Raises
    ------
    InvalidParameterError
        If the channels do not start with ``t, u, y`` or a name repeats.

    Examples
    --------
    >>> import io
    >>> from thermolab.records import REQUIRED, RUN_CHANNELS
    >>> out = io.StringIO()
    >>> w = RecordWriter(out, REQUIRED, comments=["rig: twin"])
    >>> w.write_header()
    >>> w.write_row((0.30000000000000004, 5, 0.1))
    >>> print(out.getvalue(), end="")
    # rig: twin
    t,u,y
    0.3,5.0,0.1
    """

    def __init__(
        self, stream: TextIO, channels: Sequence[ChannelSpec], *, comments: Iterable[str] = ()
    ) -> None:
        self.channels = checked_channels(channels)
        self.comments = tuple(comments)
        self._stream = stream
        self._format = _template(self.channels).format
        self._width = len(self.channels)
        self.rows = 0

    def write_header(self) -> None:
        """Write the comment lines and the header line."""
        for line in self.comments:
            for part in line.splitlines() or [""]:
                self._stream.write(f"# {part}\n")
        self._stream.write(",".join(channel_names(self.channels)) + "\n")

    def write_row(self, values: Sequence[float]) -> None:
        """Write one sample, one value per channel in channel order.

        Raises
        ------
        InvalidParameterError
            If the number of values is not the number of channels.
        """
        if len(values) != self._width:
            raise InvalidParameterError(
                f"a row of this record has {self._width} values "
                f"({','.join(channel_names(self.channels))}), got {len(values)}"
            )
        # float() first: a NumPy scalar's repr is "np.float64(...)", not a number.
        self._stream.write(self._format(*map(float, values)))
        self.rows += 1


def write_record(
    stream: TextIO,
    channels: Sequence[ChannelSpec],
    rows: Iterable[Sequence[float]],
    *,
    comments: Iterable[str] = (),
) -> int:
    """Write a whole record (header and rows) to a text stream.

    Parameters
    ----------
    stream : TextIO
        Where to write (an open file, ``io.StringIO``, an HTTP response body).
    channels : sequence of ChannelSpec
        The columns, starting with ``t, u, y``.
    rows : iterable of sequences of float
        One value per channel for each sample (consumed lazily, so a store
        can stream rows from a database cursor).
    comments : iterable of str, optional
        Lines written before the header as ``# ...``.

    Returns
    -------
    int
        The number of rows written.

    Examples
    --------
    >>> import io
    >>> from thermolab.records import REQUIRED, RUN_CHANNELS
    >>> out = io.StringIO()
    >>> write_record(out, RUN_CHANNELS[:4], [(0, 0, 1.5, 0), (1, 5, 1.5, 1)])
    2
    >>> out.getvalue().splitlines()
    ['t,u,y,k', '0,0.0,1.5,0', '1,5.0,1.5,1']
    """
    writer = RecordWriter(stream, channels, comments=comments)
    writer.write_header()
    for row in rows:
        writer.write_row(row)
    return writer.rows
