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
"""

from __future__ import annotations

import codecs
import csv
import math
import os
from array import array
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, TextIO

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError, RecordFormatError

__all__ = [
    "INDEX",
    "INPUT",
    "JITTER",
    "KNOWN_CHANNELS",
    "LATENESS",
    "OUTPUT",
    "REQUIRED",
    "RUN_CHANNELS",
    "TIME",
    "T_READ",
    "ChannelRole",
    "ChannelSpec",
    "Dialect",
    "Record",
    "RecordWriter",
    "channel_names",
    "read_record",
    "write_record",
]

ChannelRole = Literal["time", "input", "output", "setpoint", "error", "index", "timing", "other"]
"""What a channel is: the time axis, the input applied, the output read, a set
point or error signal of a controller, the sample index, the runner's timing
measurements, or anything else a rig publishes."""

_ROLES: tuple[str, ...] = ChannelRole.__args__  # type: ignore[attr-defined]


@dataclass(frozen=True, slots=True)
class ChannelSpec:
    """One named channel of a record.

    Parameters
    ----------
    name : str
        The column name (lower case letters, digits and ``_``; starts with a letter).
    unit : str, optional
        The unit (``"s"``, ``"V"``, ``"degC"``, ``""`` for a count).
    role : ChannelRole, optional
        What the channel is (default ``"other"``).
    description : str, optional
        One line for people (tooltips, ``--help``).
    integer : bool, optional
        Written as an integer (a sample index).
    digits : int or None, optional
        Significant digits written (default ``None``: the shortest text that
        reads back to the same double).

    Raises
    ------
    InvalidParameterError
        If the name, role or digits are not allowed.

    Examples
    --------
    >>> ChannelSpec("u2", "V", "input", "second heater").to_dict()
    {'name': 'u2', 'unit': 'V', 'role': 'input', 'description': 'second heater'}
    >>> ChannelSpec("2u")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: channel name '2u' must start with a lower-case ...
    """

    name: str
    unit: str = ""
    role: ChannelRole = "other"
    description: str = ""
    integer: bool = False
    digits: int | None = None

    def __post_init__(self) -> None:
        name = self.name
        if not (
            isinstance(name, str)
            and name[:1].isascii()
            and name[:1].islower()
            and all(c.isascii() and (c.islower() or c.isdigit() or c == "_") for c in name)
        ):
            raise InvalidParameterError(
                f"channel name {name!r} must start with a lower-case letter and hold only "
                "a-z, 0-9 and _"
            )
        if self.role not in _ROLES:
            raise InvalidParameterError(
                f"channel {name!r}: unknown role {self.role!r}; allowed: {', '.join(_ROLES)}"
            )
        if self.digits is not None and not (
            isinstance(self.digits, int) and 1 <= self.digits <= 17
        ):
            raise InvalidParameterError(
                f"channel {name!r}: digits must be an integer in 1..17 or None, got {self.digits!r}"
            )

    def to_dict(self) -> dict[str, str]:
        """Return ``{"name", "unit", "role", "description"}`` (JSON-ready).

        Examples
        --------
        >>> TIME.to_dict()
        {'name': 't', 'unit': 's', 'role': 'time', 'description': 'scheduled time of the sample'}
        """
        return {
            "name": self.name,
            "unit": self.unit,
            "role": self.role,
            "description": self.description,
        }


TIME = ChannelSpec("t", "s", "time", "scheduled time of the sample", digits=12)
INPUT = ChannelSpec("u", "V", "input", "input applied from this sample to the next")
OUTPUT = ChannelSpec("y", "V", "output", "output read at this sample")
INDEX = ChannelSpec("k", "", "index", "sample index", integer=True)
T_READ = ChannelSpec("t_read", "s", "timing", "when the rig took the reading")
JITTER = ChannelSpec("jitter", "s", "timing", "t_read - t, the acquisition's timing error")
LATENESS = ChannelSpec("lateness", "s", "timing", "how late the loop woke for this sample")

REQUIRED: tuple[ChannelSpec, ...] = (TIME, INPUT, OUTPUT)
"""The channels every record has, first, in this order (what the methods need)."""

RUN_CHANNELS: tuple[ChannelSpec, ...] = (*REQUIRED, INDEX, T_READ, JITTER, LATENESS)
"""The channels of a runner's record, in column order (``t,u,y,k,t_read,jitter,lateness``)."""

KNOWN_CHANNELS: Mapping[str, ChannelSpec] = {c.name: c for c in RUN_CHANNELS}
"""Channels recognised by name when a file is read (others get role ``"other"``)."""


def channel_names(channels: Iterable[ChannelSpec]) -> tuple[str, ...]:
    """The column names of a channel list.

    Examples
    --------
    >>> ",".join(channel_names(RUN_CHANNELS))
    't,u,y,k,t_read,jitter,lateness'
    """
    return tuple(c.name for c in channels)


def _checked_channels(channels: Sequence[ChannelSpec]) -> tuple[ChannelSpec, ...]:
    from thermolab.errors import InvalidParameterError

    channels = tuple(channels)
    names = channel_names(channels)
    if names[:3] != channel_names(REQUIRED):
        raise InvalidParameterError(
            f"a record's channels start with t, u, y; got {', '.join(names) or 'none'}"
        )
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise InvalidParameterError(f"channel {name!r} appears twice in the record")
        seen.add(name)
    return channels


# -- writing ------------------------------------------------------------------------------


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
        self.channels = _checked_channels(channels)
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


# -- reading ------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Dialect:
    """How a file was written, as found by :func:`read_record`.

    Attributes
    ----------
    delimiter : str
        ``","``, ``";"`` or ``"\\t"``.
    decimal : str
        ``"."`` or ``","``.
    encoding : str
        ``"utf-8"``, ``"utf-8-sig"`` (with a byte-order mark) or ``"latin-1"``.
    """

    delimiter: str = ","
    decimal: str = "."
    encoding: str = "utf-8"


@dataclass(frozen=True)
class Record:
    """A record read from a file: named channels as float arrays.

    Attributes
    ----------
    channels : tuple of ChannelSpec
        The channels read, ``t, u, y`` first.
    columns : mapping of str to numpy.ndarray
        One float64 array per channel. ``t`` is strictly increasing and
        ``t, u, y`` are finite; other channels may hold NaN for empty cells.
    comments : tuple of str
        The ``#`` lines before the header, without the ``#``.
    dialect : Dialect
        The separator, decimal mark and encoding found.
    """

    channels: tuple[ChannelSpec, ...]
    columns: Mapping[str, npt.NDArray[np.float64]]
    comments: tuple[str, ...] = ()
    dialect: Dialect = field(default_factory=Dialect)

    @property
    def t(self) -> npt.NDArray[np.float64]:
        """Times (s)."""
        return self.columns["t"]

    @property
    def u(self) -> npt.NDArray[np.float64]:
        """Inputs."""
        return self.columns["u"]

    @property
    def y(self) -> npt.NDArray[np.float64]:
        """Outputs."""
        return self.columns["y"]

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def median_dt(self) -> float:
        """The median spacing of ``t``."""
        return float(np.median(np.diff(self.t)))

    def __getitem__(self, name: str) -> npt.NDArray[np.float64]:
        return self.columns[name]


_SEPARATORS = (",", ";", "\t")
_SEPARATOR_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}
_HEAD_BYTES = 1 << 16
_SNIFF_LINES = 50


def read_record(
    source: str | os.PathLike[str],
    *,
    channels: Iterable[str] | None = None,
    known: Iterable[ChannelSpec] = (),
    min_rows: int = 3,
) -> Record:
    """Read a record from a CSV file.

    Parameters
    ----------
    source : str or os.PathLike
        The file. Its first line that is neither blank nor a ``#`` comment is
        the header, naming at least ``t``, ``u`` and ``y`` (any order, case
        and surrounding spaces ignored).
    channels : iterable of str, optional
        The columns to read besides ``t, u, y`` (default: every column).
        Reading only what is needed saves memory on large files.
    known : iterable of ChannelSpec, optional
        Specs for columns that are not among :data:`KNOWN_CHANNELS` (a CSV
        carries names only); other unknown columns get ``ChannelSpec(name)``.
    min_rows : int, optional
        The fewest samples accepted (default 3).

    Returns
    -------
    Record
        ``t, u, y`` and the other channels as float arrays.

    Raises
    ------
    RecordFormatError
        One line naming the file and, for a bad cell, its line, sample and
        column: missing or unreadable file, binary or UTF-16 data, an
        ambiguous separator or decimal mark, missing or repeated columns,
        too few rows, a row with the wrong number of cells, a cell that is
        not a number, a non-finite ``t``, ``u`` or ``y``, or ``t`` not strictly
        increasing.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = pathlib.Path(folder) / "planilha.csv"
    ...     _ = path.write_bytes("\\ufefft;u;y;r\\n0;0;1;2\\n1;5;1,5;2\\n2;5;2;2,5\\n".encode())
    ...     record = read_record(path)
    >>> record.y, record["r"]
    (array([1. , 1.5, 2. ]), array([2. , 2. , 2.5]))
    >>> record.dialect
    Dialect(delimiter=';', decimal=',', encoding='utf-8-sig')
    """
    path = Path(source)
    head = _read_head(path)
    encoding = _encoding(path, head)
    start = len(codecs.BOM_UTF8) if encoding == "utf-8-sig" else 0
    complete = head if len(head) < _HEAD_BYTES else head[: head.rfind(b"\n") + 1]
    lines = complete[start:].decode(encoding.removesuffix("-sig"), errors="replace").split("\n")
    comments: list[str] = []
    header_index = None
    for i, line in enumerate(lines):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            comments.append(stripped[1:].strip())
            continue
        header_index = i
        break
    if header_index is None:
        if len(head) == _HEAD_BYTES:
            raise RecordFormatError(f"{path}: no header in the first {_HEAD_BYTES} bytes")
        raise RecordFormatError(f"{path}: empty file; expected a header with the columns t,u,y")
    header_line = lines[header_index].rstrip("\r")
    samples = [
        (header_index + 2 + j, line.rstrip("\r"))
        for j, line in enumerate(lines[header_index + 1 :])
        if line.strip() and not line.lstrip().startswith("#")
    ][:_SNIFF_LINES]
    delimiter = _delimiter(path, header_index + 1, header_line, samples)
    header = next(csv.reader([header_line], delimiter=delimiter))
    names = [c.strip().lower() for c in header]
    wanted = _wanted(path, header_index + 1, header, names, channels)
    decimal = _decimal(path, delimiter, names, samples)
    dialect = Dialect(delimiter, decimal or ".", encoding)
    # Bytes up to the end of the header line (the newline after it, if any).
    body = start
    for _ in range(header_index + 1):
        newline = complete.find(b"\n", body)
        body = len(complete) if newline < 0 else newline + 1
    columns = _fast_columns(path, body, names, wanted, dialect)
    if columns is None or not _plausible(columns):
        columns, dialect = _exact_columns(path, header_index + 1, names, wanted, dialect, decimal)
    n = int(columns["t"].size)
    if n < min_rows:
        raise RecordFormatError(
            f"{path}: too few rows: {n} sample{'s' if n != 1 else ''}, "
            f"at least {min_rows} are needed"
        )
    declared = {**KNOWN_CHANNELS, **{c.name: c for c in known}}
    specs = tuple(declared.get(name) or ChannelSpec(name) for name in wanted)
    return Record(channels=specs, columns=columns, comments=tuple(comments), dialect=dialect)


def _read_head(path: Path) -> bytes:
    try:
        with path.open("rb") as fh:
            return fh.read(_HEAD_BYTES)
    except FileNotFoundError:
        raise RecordFormatError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise RecordFormatError(f"{path}: is a directory, not a CSV file") from None
    except OSError as exc:
        raise RecordFormatError(f"{path}: cannot read ({exc.strerror or exc})") from None


def _encoding(path: Path, head: bytes) -> str:
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise RecordFormatError(
            f"{path}: not a CSV text file this reader takes: it is UTF-16 text "
            "(save it as UTF-8 or Latin-1 CSV)"
        )
    nul = head.find(b"\x00")
    if nul >= 0:
        raise RecordFormatError(
            f"{path}: not a CSV text file (binary data: a NUL byte at byte {nul})"
        )
    if head.startswith(codecs.BOM_UTF8):
        return "utf-8-sig"
    try:
        # A multi-byte character cut by the end of the head is not an error.
        codecs.getincrementaldecoder("utf-8")().decode(head, final=False)
    except UnicodeDecodeError:
        return "latin-1"  # every byte is a Latin-1 character
    return "utf-8"


def _delimiter(path: Path, line: int, header: str, samples: list[tuple[int, str]]) -> str:
    present = [d for d in _SEPARATORS if d in header]
    if len(present) <= 1:
        return present[0] if present else ","
    # Several candidates in the header: the one that splits every line alike.
    consistent = [
        d for d in present if all(text.count(d) == header.count(d) for _, text in samples)
    ]
    if len(consistent) == 1:
        return consistent[0]
    shown = " and ".join(_SEPARATOR_NAMES[d] for d in present)
    raise RecordFormatError(
        f"{path}: line {line}: the header {header.strip()!r} holds both {shown} separators; "
        "separate the columns with one of comma, semicolon or tab"
    )


def _wanted(
    path: Path,
    line: int,
    header: list[str],
    names: list[str],
    channels: Iterable[str] | None,
) -> tuple[str, ...]:
    required = channel_names(REQUIRED)
    missing = [c for c in required if c not in names]
    if missing:
        shown = ",".join(c.strip() for c in header)
        if len(shown) > 60:
            shown = shown[:57] + "..."
        raise RecordFormatError(
            f"{path}: the header (line {line}) lacks the column"
            f"{'s' if len(missing) > 1 else ''} {', '.join(missing)}; it needs t,u,y "
            f"(got {shown!r})"
        )
    if channels is None:
        extra = [n for n in dict.fromkeys(names) if n and n not in required]
    else:
        extra = [n for n in dict.fromkeys(channels) if n not in required]
        absent = [n for n in extra if n not in names]
        if absent:
            raise RecordFormatError(
                f"{path}: the header (line {line}) lacks the column"
                f"{'s' if len(absent) > 1 else ''} {', '.join(absent)}"
            )
    for name in (*required, *extra):
        if names.count(name) > 1:
            raise RecordFormatError(
                f"{path}: the header (line {line}) names the column {name!r} "
                f"{names.count(name)} times; each column needs its own name"
            )
        if not _valid_name(name):
            raise RecordFormatError(
                f"{path}: the header (line {line}) has the column {name!r}; a channel name "
                "starts with a letter and holds only a-z, 0-9 and _"
            )
    return (*required, *extra)


def _valid_name(name: str) -> bool:
    try:
        ChannelSpec(name)
    except ValueError:
        return False
    return True


def _decimal(
    path: Path, delimiter: str, names: list[str], samples: list[tuple[int, str]]
) -> str | None:
    """The decimal mark the first lines show (None: none seen yet)."""
    if delimiter == ",":
        return "."
    found: dict[str, tuple[int, str, str]] = {}
    for line, text in samples:
        for j, cell in enumerate(text.split(delimiter)):
            cell = cell.strip()
            column = names[j] if j < len(names) else f"#{j + 1}"
            _check_cell_marks(path, line, column, cell)
            for mark in (".", ","):
                if mark in cell and mark not in found:
                    found[mark] = (line, column, cell)
    if len(found) == 2:
        raise _mixed_marks(path, found["."], found[","])
    return next(iter(found), None)


def _check_cell_marks(path: Path, line: int, column: str, cell: str) -> None:
    if "." in cell and "," in cell:
        raise RecordFormatError(
            f"{path}: line {line}, column {column}: {cell!r} mixes '.' and ',' "
            "(thousands separators are not supported); write plain numbers"
        )


def _mixed_marks(
    path: Path, dot: tuple[int, str, str], comma: tuple[int, str, str]
) -> RecordFormatError:
    (l1, c1, v1), (l2, c2, v2) = sorted((dot, comma))
    return RecordFormatError(
        f"{path}: ambiguous decimal mark: line {l1}, column {c1} has {v1!r} but line {l2}, "
        f"column {c2} has {v2!r}; use one decimal mark throughout"
    )


def _fast_columns(
    path: Path,
    body: int,
    names: list[str],
    wanted: tuple[str, ...],
    dialect: Dialect,
) -> dict[str, npt.NDArray[np.float64]] | None:
    """Parse the columns after the header with pyarrow; None if it refuses the file."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    # Stand-in names: the header may repeat or leave empty a column nobody asked for.
    column_names = [f"c{j}" for j in range(len(names))]
    include = [f"c{names.index(n)}" for n in wanted]
    try:
        with pa.OSFile(str(path)) as stream:
            stream.seek(body)
            table = pacsv.read_csv(
                stream,
                read_options=pacsv.ReadOptions(
                    column_names=column_names,
                    encoding="utf8" if dialect.encoding.startswith("utf-8") else "latin1",
                ),
                parse_options=pacsv.ParseOptions(delimiter=dialect.delimiter),
                convert_options=pacsv.ConvertOptions(
                    include_columns=include,
                    column_types=dict.fromkeys(include, pa.float64()),
                    decimal_point=dialect.decimal,
                ),
            )
    except (pa.ArrowException, OSError, UnicodeDecodeError):
        return None
    columns: dict[str, npt.NDArray[np.float64]] = {}
    for name, key in zip(wanted, include, strict=True):
        # One column at a time, each Arrow column released once copied: the
        # peak is one Arrow column above the NumPy arrays.
        chunked = table.column(key)
        table = table.drop_columns([key])
        columns[name] = _to_numpy(chunked)
        del chunked
    del table
    # Arrow's allocator keeps freed blocks for reuse (about the size of the
    # table); hand them back, or they stay in the process's memory while the
    # identification that follows allocates its own.
    pa.default_memory_pool().release_unused()
    return columns


def _to_numpy(chunked: object) -> npt.NDArray[np.float64]:
    """Copy a float64 Arrow column into one NumPy array, nulls (empty cells) as NaN.

    By hand rather than ``ChunkedArray.to_numpy()``, which imports pandas when
    it is installed (over a second of start-up for a command line).
    """
    import pyarrow.compute as pac

    out = np.empty(len(chunked), dtype=np.float64)  # type: ignore[arg-type]
    at = 0
    for chunk in chunked.chunks:  # type: ignore[attr-defined]
        if chunk.null_count:
            chunk = pac.fill_null(chunk, math.nan)
        size = len(chunk)
        data = chunk.buffers()[1]
        out[at : at + size] = np.frombuffer(
            data, dtype=np.float64, count=size, offset=chunk.offset * 8
        )
        at += size
    return out


def _plausible(columns: Mapping[str, npt.NDArray[np.float64]]) -> bool:
    """True if the fast reader's t, u, y need no diagnosis (finite, t increasing)."""
    for name in channel_names(REQUIRED):
        if not np.isfinite(columns[name]).all():
            return False
    t = columns["t"]
    return bool(t.size < 2 or (t[1:] > t[:-1]).all())


def _exact_columns(
    path: Path,
    header_line: int,
    names: list[str],
    wanted: tuple[str, ...],
    dialect: Dialect,
    decimal: str | None,
) -> tuple[dict[str, npt.NDArray[np.float64]], Dialect]:
    """Read the file with the csv module: the reference semantics, with exact diagnostics."""
    encoding = dialect.encoding
    try:
        return _exact_read(path, header_line, names, wanted, dialect, decimal, encoding)
    except UnicodeDecodeError:
        # UTF-8 in the first 64 KiB but not further on: a Latin-1 file after all.
        return _exact_read(path, header_line, names, wanted, dialect, decimal, "latin-1")


def _exact_read(
    path: Path,
    header_line: int,
    names: list[str],
    wanted: tuple[str, ...],
    dialect: Dialect,
    decimal: str | None,
    encoding: str,
) -> tuple[dict[str, npt.NDArray[np.float64]], Dialect]:
    index = [names.index(n) for n in wanted]
    required = len(REQUIRED)
    width = len(names)
    delimiter = dialect.delimiter
    first_mark: tuple[int, str, str] | None = None
    # array('d'): 8 bytes a value, where a list of floats takes 32.
    values = [array("d") for _ in wanted]
    appends = [v.append for v in values]
    previous_t = -math.inf
    try:
        fh = path.open(newline="", encoding=encoding)
    except OSError as exc:
        raise RecordFormatError(f"{path}: cannot read ({exc.strerror or exc})") from None
    with fh:
        reader = csv.reader(fh, delimiter=delimiter)
        sample = 0
        for row in reader:
            line = reader.line_num
            if line <= header_line:
                continue
            if not row or not any(c.strip() for c in row) or row[0].lstrip().startswith("#"):
                continue
            if len(row) != width:
                hint = ""
                if delimiter == "," and len(row) > width:
                    hint = " (decimal commas need a ';' or tab separator)"
                raise RecordFormatError(
                    f"{path}: line {line} (sample {sample}) has {len(row)} cells, the header "
                    f"has {width}{hint}"
                )
            for c, (name, j) in enumerate(zip(wanted, index, strict=True)):
                cell = row[j].strip()
                if not cell:
                    if c < required:
                        raise RecordFormatError(
                            f"{path}: line {line} (sample {sample}), column {name}: empty; "
                            "t, u and y need a number in every row"
                        )
                    appends[c](math.nan)
                    continue
                if delimiter != ",":
                    _check_cell_marks(path, line, name, cell)
                    for mark in (".", ","):
                        if mark not in cell:
                            continue
                        if decimal is None:
                            decimal, first_mark = mark, (line, name, cell)
                        elif mark != decimal:
                            other = first_mark or (0, "?", "?")
                            raise _mixed_marks(path, other, (line, name, cell))
                    if decimal == ",":
                        cell = cell.replace(",", ".")
                if first_mark is None and decimal is not None and "." in cell:
                    first_mark = (line, name, cell)
                try:
                    if "_" in cell:  # float() takes 1_000; no spreadsheet writes it
                        raise ValueError(cell)
                    v = float(cell)
                except ValueError:
                    raise RecordFormatError(
                        f"{path}: line {line} (sample {sample}), column {name}: "
                        f"{row[j].strip()!r} is not a number"
                    ) from None
                if c < required and not math.isfinite(v):
                    raise RecordFormatError(
                        f"{path}: line {line} (sample {sample}), column {name}: "
                        f"{row[j].strip()!r} is not finite (NaN or inf); remove or repair the row"
                    )
                if c == 0:
                    if not v > previous_t:
                        raise RecordFormatError(
                            f"{path}: line {line} (sample {sample}): t = {v!r} does not "
                            f"increase (previous t = {previous_t!r}); t must be strictly "
                            "increasing"
                        )
                    previous_t = v
                appends[c](v)
            sample += 1
    columns = {
        name: np.frombuffer(v, dtype=np.float64).copy()
        for name, v in zip(wanted, values, strict=True)
    }
    return columns, Dialect(delimiter, decimal or ".", encoding)
