"""Run records: named channels, and the CSV text that carries them.

A record is a table of samples whose columns are *channels*: the time, the
input and the output that every method needs, plus whatever else a rig or a
controller publishes (a set point, an error signal, a second heater or
sensor) and the runner's own timing (sample index, time of the reading,
jitter, lateness). Each channel is declared once as a :class:`ChannelSpec`
(name, unit, role); the CSV header, the runner's events and the lab's export
derive their columns from the channel list, as TCLab's ``Historian(sources)``
derives its columns from its sources.

Writing
    :class:`RecordWriter` (one row at a time, for the runner) and
    :func:`write_record` (an iterator of rows, for an export) write a header
    of channel names and one line per sample. Floats are written as the
    shortest text that reads back to the same double (``repr``), so
    identifying a written record reproduces the online estimates bit for
    bit; a channel may ask for fewer digits (the scheduled time, 12
    significant digits, so ``3 * 0.1`` prints ``0.3``).

Reading
    :func:`read_record` reads what this module writes and what a spreadsheet
    exports: comma, semicolon or tab separators; decimal commas (``1,5``
    with a ``;`` or tab separator); UTF-8 with or without a byte-order mark,
    or Latin-1; ``#`` comment lines and blank lines anywhere. Bad input
    raises :class:`~thermolab.errors.RecordFormatError` with one line naming
    the file, the line, the column and what was expected.

    The columns are parsed by ``pyarrow.csv`` (multi-threaded C++, about
    0.3 s per million rows here, memory proportional to the columns kept).
    When the fast reader refuses a file, or the file is unusual (comment
    lines between samples, a decimal comma that appears late), the file is
    read again by an exact pure-Python reader built on the ``csv`` module,
    which either reads it or names the first bad line. The exact reader is
    the specification; the fast one is an accelerator that must agree with
    it (the tests check both on the same files).

Modules: :mod:`~thermolab.records.channels` (``ChannelSpec`` and the
standard channels), :mod:`~thermolab.records.writing`,
:mod:`~thermolab.records.reading` (dialect sniffing and the pyarrow reader),
``_exact`` (the exact reader) and :mod:`~thermolab.records.dialect`.
"""

from thermolab.records import channels as _channels

# Every public name of channels, as its __all__ lists them (not a second list here).
from thermolab.records.channels import *  # noqa: F403
from thermolab.records.reading import Dialect, Record, read_record
from thermolab.records.writing import RecordWriter, write_record

__all__ = [
    *_channels.__all__,
    "Dialect",
    "Record",
    "RecordWriter",
    "read_record",
    "write_record",
]
