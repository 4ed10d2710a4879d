"""Reading records: any spreadsheet's CSV into named float columns, or one clear error."""

from __future__ import annotations

import codecs
import csv
import dataclasses
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import numpy.typing as npt

from thermolab.errors import RecordFormatError
from thermolab.records._exact import check_cell_marks, exact_columns, mixed_marks
from thermolab.records._mapping import KNOWN_LAYOUTS, map_columns, parse_assignments, split_unit
from thermolab.records.channels import KNOWN_CHANNELS, REQUIRED, ChannelSpec, channel_names
from thermolab.records.dialect import Dialect

__all__ = ["Dialect", "Record", "read_record"]


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
    merged_times : tuple of (int, float) or None
        With ``equal_times="last"``: how many rows shared their time with the
        next and were dropped, and the first such time; None if none.
    """

    channels: tuple[ChannelSpec, ...]
    columns: Mapping[str, npt.NDArray[np.float64]]
    comments: tuple[str, ...] = ()
    dialect: Dialect = field(default_factory=Dialect)
    merged_times: tuple[int, float] | None = None

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
    def units(self) -> dict[str, str]:
        """The unit of every channel (``""`` where the file does not say)."""
        return {c.name: c.unit for c in self.channels}

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
    columns: Mapping[str, str | int] | str | None = None,
    units: Mapping[str, str] | str | None = None,
    header: bool | None = None,
    equal_times: Literal["refuse", "last"] = "refuse",
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
    columns : mapping or str, optional
        Which columns are ``t``, ``u`` and ``y``: a header name (with or
        without its unit, any case) or a 1-based position, as a mapping or as
        text ``"t=Time,u=Q1,y=T1"`` / ``"t=1,u=2,y=3"``. Default: the columns
        named ``t, u, y``, else a known layout (the ``tclab`` Historian's
        ``Time, T1, T2, Q1, Q2``: heater 1).
    units : mapping or str, optional
        Units of ``t, u, y`` (``"u=%,y=°C"``), over those in the header
        (``T1 (°C)``, ``Time [s]``).
    header : bool, optional
        Whether the first line that is not a comment is a header (default:
        it is, unless every cell is a number; a file without one needs
        positions in ``columns``).
    equal_times : {"refuse", "last"}, optional
        Rows whose time equals the previous row's: refused (the default), or
        merged into the last of them (the latest reading at that time); the
        record's ``merged_times`` says how many rows were dropped and where.

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
    first = next(csv.reader([header_line], delimiter=delimiter))
    column_map: Mapping[str, str | int] | None = (
        parse_assignments(columns, "columns") if isinstance(columns, str) else columns
    )
    given_units = parse_assignments(units, "units") if isinstance(units, str) else dict(units or {})
    has_header = header if header is not None else not all(_is_number(c) for c in first)
    if not has_header and column_map is not None:
        # No header: the first line is a sample; columns are named c1, c2, ...
        samples = [(header_index + 1, header_line), *samples][:_SNIFF_LINES]
        split = [(f"c{j + 1}", "") for j in range(len(first))]
        skip = header_index
    else:
        split = [split_unit(c) for c in first]
        skip = header_index + 1
    names = [n.lower() for n, _ in split]
    layout_units: dict[str, str] = {}
    if column_map is None and has_header and not {"t", "u", "y"} <= set(names):
        for layout, layout_unit in KNOWN_LAYOUTS:
            if all(names.count(v) == 1 for v in layout.values()):
                column_map, layout_units = dict(layout), dict(layout_unit)
                break
    if column_map is not None:
        where = map_columns(
            path, header_index + 1, first if has_header else None, len(first), column_map
        )
        names = _other_names(names, where)
        # A file that is not the lab's own: its units are what it says, not volts.
        layout_units = {"t": "s", "u": "", "y": "", **layout_units}
    said = {names[j]: unit for j, (_, unit) in enumerate(split) if unit}
    unit_of = {**layout_units, **said, **given_units}
    wanted = _wanted(path, header_index + 1, first, names, channels)
    decimal = _decimal(path, delimiter, names, samples)
    dialect = Dialect(delimiter, decimal or ".", encoding)
    # Bytes up to the end of the header line (the newline after it, if any).
    body = start
    for _ in range(skip):
        newline = complete.find(b"\n", body)
        body = len(complete) if newline < 0 else newline + 1
    if equal_times not in ("refuse", "last"):
        raise ValueError(f"equal_times must be 'refuse' or 'last', got {equal_times!r}")
    merge = equal_times == "last"
    arrays = _fast_columns(path, body, names, wanted, dialect)
    if arrays is None or not _plausible(arrays, merge):
        arrays, dialect = exact_columns(path, skip, names, wanted, dialect, decimal, merge)
    merged: tuple[int, float] | None = None
    if merge:
        t = arrays["t"]
        dropped = np.flatnonzero(t[1:] == t[:-1])
        if dropped.size:
            keep = np.ones(t.size, dtype=bool)
            keep[dropped] = False  # the earlier of two rows at one time
            merged = (int(dropped.size), float(t[dropped[0]]))
            arrays = {k: np.ascontiguousarray(v[keep]) for k, v in arrays.items()}
    n = int(arrays["t"].size)
    if n < min_rows:
        raise RecordFormatError(
            f"{path}: too few rows: {n} sample{'s' if n != 1 else ''}, "
            f"at least {min_rows} are needed"
        )
    declared = {**KNOWN_CHANNELS, **{c.name: c for c in known}}
    specs = tuple(declared.get(name) or ChannelSpec(name) for name in wanted)
    specs = tuple(
        dataclasses.replace(c, unit=unit_of[c.name]) if c.name in unit_of else c for c in specs
    )
    return Record(
        channels=specs,
        columns=arrays,
        comments=tuple(comments),
        dialect=dialect,
        merged_times=merged,
    )


def _is_number(cell: str) -> bool:
    try:
        float(cell.strip().replace(",", "."))
    except ValueError:
        return False
    return True


def _other_names(names: list[str], where: Mapping[str, int]) -> list[str]:
    """Header names with t, u, y at the mapped columns; other columns as valid, distinct names."""
    out: list[str] = []
    for j, name in enumerate(names):
        clean = "_".join("".join(c if c.isascii() and c.isalnum() else " " for c in name).split())
        if not clean or not clean[0].isalpha():
            clean = f"c{j + 1}" if not clean else f"c{j + 1}_{clean}"
        out.append(clean)
    for key, j in where.items():
        out[j] = key
    taken: set[str] = set()
    for j, name in enumerate(out):
        if name in taken or (name in ("t", "u", "y") and where.get(name) != j):
            out[j] = f"{name}_{j + 1}"
        taken.add(out[j])
    return out


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
            check_cell_marks(path, line, column, cell)
            for mark in (".", ","):
                if mark in cell and mark not in found:
                    found[mark] = (line, column, cell)
    if len(found) == 2:
        raise mixed_marks(path, found["."], found[","])
    return next(iter(found), None)


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
                    # 8 MiB blocks (default 1 MiB): an eighth of the chunks to
                    # copy, and 10-30 % less CPU on a 10^7-row file here.
                    block_size=1 << 23,
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


def _plausible(columns: Mapping[str, npt.NDArray[np.float64]], equal: bool = False) -> bool:
    """True if the fast reader's t, u, y need no diagnosis (finite, t increasing)."""
    for name in channel_names(REQUIRED):
        if not np.isfinite(columns[name]).all():
            return False
    t = columns["t"]
    if equal:
        return bool(t.size < 2 or (t[1:] >= t[:-1]).all())
    return bool(t.size < 2 or (t[1:] > t[:-1]).all())
