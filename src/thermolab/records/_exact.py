"""The exact reader: the csv module, one cell at a time, naming the first bad line.

It is the specification of what :func:`thermolab.records.read_record`
accepts; the pyarrow reader is an accelerator that must agree with it.
"""

from __future__ import annotations

import csv
import math
from array import array
from pathlib import Path

import numpy as np
import numpy.typing as npt

from thermolab.errors import RecordFormatError
from thermolab.records.channels import REQUIRED
from thermolab.records.dialect import Dialect

__all__ = ["check_cell_marks", "exact_columns", "mixed_marks"]


def check_cell_marks(path: Path, line: int, column: str, cell: str) -> None:
    """Refuse a cell with both decimal marks (``1.000,5``: a thousands separator)."""
    if "." in cell and "," in cell:
        raise RecordFormatError(
            f"{path}: line {line}, column {column}: {cell!r} mixes '.' and ',' "
            "(thousands separators are not supported); write plain numbers"
        )


def mixed_marks(
    path: Path, dot: tuple[int, str, str], comma: tuple[int, str, str]
) -> RecordFormatError:
    """The error for a file that uses both decimal marks, naming both places."""
    (l1, c1, v1), (l2, c2, v2) = sorted((dot, comma))
    return RecordFormatError(
        f"{path}: ambiguous decimal mark: line {l1}, column {c1} has {v1!r} but line {l2}, "
        f"column {c2} has {v2!r}; use one decimal mark throughout"
    )


def exact_columns(
    path: Path,
    header_line: int,
    names: list[str],
    wanted: tuple[str, ...],
    dialect: Dialect,
    decimal: str | None,
    equal_times: bool = False,
) -> tuple[dict[str, npt.NDArray[np.float64]], Dialect]:
    """Read the file with the csv module: the reference semantics, with exact diagnostics.

    ``equal_times``: a time equal to the previous one is read (the caller merges them).
    """
    encoding = dialect.encoding
    args = (path, header_line, names, wanted, dialect, decimal)
    try:
        return _exact_read(*args, encoding, equal_times)
    except UnicodeDecodeError:
        # UTF-8 in the first 64 KiB but not further on: a Latin-1 file after all.
        return _exact_read(*args, "latin-1", equal_times)


def _exact_read(
    path: Path,
    header_line: int,
    names: list[str],
    wanted: tuple[str, ...],
    dialect: Dialect,
    decimal: str | None,
    encoding: str,
    equal_times: bool = False,
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
                    check_cell_marks(path, line, name, cell)
                    for mark in (".", ","):
                        if mark not in cell:
                            continue
                        if decimal is None:
                            decimal, first_mark = mark, (line, name, cell)
                        elif mark != decimal:
                            other = first_mark or (0, "?", "?")
                            raise mixed_marks(path, other, (line, name, cell))
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
                    if not (v > previous_t or (equal_times and v == previous_t)):
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
