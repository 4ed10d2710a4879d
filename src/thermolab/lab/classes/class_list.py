"""Reading a class list: a CSV file of login names and display names.

The file is what a school's system or a spreadsheet exports: a header with
``username`` and ``display_name`` (in any order, any case; ``name`` is taken
for ``display_name``), comma, semicolon or tab separated, UTF-8 with or
without a BOM. Every bad line is reported, not only the first, and a file with
any bad line is refused whole (:class:`~thermolab.errors.ClassListError`): a
teacher fixes the file and uploads it again.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

from thermolab.errors import ClassListError, InvalidParameterError
from thermolab.lab.accounts.names import normalize_display_name, normalize_username

__all__ = ["MAX_CLASS_LIST_BYTES", "MAX_CLASS_LIST_ROWS", "ClassListEntry", "parse_class_list"]

MAX_CLASS_LIST_BYTES = 1_000_000
MAX_CLASS_LIST_ROWS = 5000
_COLUMNS = {"username": "username", "display_name": "display_name", "name": "display_name"}
_SEPARATORS = (",", ";", "\t")


@dataclass(frozen=True, slots=True)
class ClassListEntry:
    """One student of a class list: the login name (normal form) and the name as written."""

    line: int
    username: str
    display_name: str


def parse_class_list(data: bytes) -> list[ClassListEntry]:
    """Return the students of a class list, or raise with every bad line.

    Raises
    ------
    ClassListError
        Not UTF-8 (the line of the first bad byte), a header without the two
        columns or with unknown ones, a line with the wrong number of cells,
        a bad login or display name, or a login name twice (case and accents
        do not count: ``João`` and ``joao`` are the same person).

    Examples
    --------
    >>> [e.username for e in parse_class_list("username;name\\nJoão;João Silva\\n".encode())]
    ['joao']
    """
    if len(data) > MAX_CLASS_LIST_BYTES:
        raise ClassListError([(0, f"the file is larger than {MAX_CLASS_LIST_BYTES} bytes")])
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ClassListError(
            [(line, "the file is not UTF-8 text; save it as 'CSV UTF-8' and upload it again")]
        ) from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise ClassListError([(1, "the file is empty; the first line must be the header")])
    header = lines[0]
    separator = max(_SEPARATORS, key=header.count)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=separator, strict=True)
    # (physical line where the row starts, cells): a quoted cell may span lines.
    rows: list[tuple[int, list[str]]] = []
    try:
        start = 1
        for row in reader:
            rows.append((start, row))
            start = reader.line_num + 1
    except csv.Error as exc:
        raise ClassListError([(reader.line_num, f"not readable as CSV ({exc})")]) from None
    header_cells = rows[0][1]
    columns = [cell.strip().lower().replace(" ", "_") for cell in header_cells]
    unknown = [c for c in columns if c not in _COLUMNS]
    named = [_COLUMNS[c] for c in columns if c in _COLUMNS]
    if unknown or sorted(named) != ["display_name", "username"]:
        raise ClassListError(
            [
                (
                    1,
                    f"the header has columns {header_cells!r}; it must have exactly 'username' and "
                    "'display_name' (or 'name')",
                )
            ]
        )
    if len(rows) - 1 > MAX_CLASS_LIST_ROWS:
        raise ClassListError([(0, f"more than {MAX_CLASS_LIST_ROWS} students in one list")])
    where = {_COLUMNS[c]: i for i, c in enumerate(columns)}
    problems: list[tuple[int, str]] = []
    entries: list[ClassListEntry] = []
    first_line: dict[str, int] = {}
    for number, row in rows[1:]:
        if not any(cell.strip() for cell in row):
            continue
        if len(row) != len(columns):
            problems.append((number, f"{len(row)} cells where the header has {len(columns)}"))
            continue
        try:
            username = normalize_username(row[where["username"]])
            display_name = normalize_display_name(row[where["display_name"]])
        except InvalidParameterError as exc:
            problems.append((number, str(exc)))
            continue
        if username in first_line:
            problems.append(
                (number, f"login name {username!r} is already on line {first_line[username]}")
            )
            continue
        first_line[username] = number
        entries.append(ClassListEntry(number, username, display_name))
    if problems:
        raise ClassListError(problems)
    if not entries:
        raise ClassListError([(2, "the list has a header but no student")])
    return entries
