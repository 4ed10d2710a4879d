"""Reading a class list: a CSV file of login names and display names, as schools save them.

The file is what a school's system or a spreadsheet exports:

- a header naming a login column and a name column, in English, Portuguese or
  Spanish, in any order, case or accents (``username;display_name``,
  ``matrícula;nome``, ``usuário;nome completo``, ``usuario;nombre completo``,
  ``correo;nombre``...: every word taken is in :data:`HEADER_SYNONYMS`, the one
  table of them);
- comma, semicolon or tab separated (the separator the header uses most);
- UTF-8 with or without a BOM, UTF-16 with a BOM (Excel's "Unicode text"), or
  Windows-1252 / Latin-1 (Excel's plain "CSV" on a Brazilian or Spanish
  Windows). :func:`decode_class_list` tries UTF-8 first: a Windows-1252 file
  with an accented letter is almost never valid UTF-8 (a letter's byte there
  is never followed by a continuation byte), so the guess is safe for names;
  the encoding used is reported.

Every bad line is reported, not only the first, each as a
:class:`~thermolab.errors.ClassListProblem` with a stable code, and a file with
any bad line is refused whole (:class:`~thermolab.errors.ClassListError`): a
teacher fixes the file and uploads it again.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Mapping
from dataclasses import dataclass

from thermolab.errors import ClassListError, ClassListProblem, InvalidParameterError
from thermolab.lab.accounts.names import (
    MAX_DISPLAY_NAME,
    MAX_USERNAME,
    normalize_display_name,
    normalize_username,
    username_form,
)

__all__ = [
    "HEADER_SYNONYMS",
    "MAX_CLASS_LIST_BYTES",
    "MAX_CLASS_LIST_ROWS",
    "ClassList",
    "ClassListEntry",
    "decode_class_list",
    "header_column",
    "parse_class_list",
    "read_class_list",
]

MAX_CLASS_LIST_BYTES = 1_000_000
MAX_CLASS_LIST_ROWS = 5000

#: The words a header may use for each column, folded (no case, no accents, ``_``
#: for spaces and hyphens): English, then Portuguese, then Spanish. A header
#: names exactly one column of each.
HEADER_SYNONYMS: Mapping[str, tuple[str, ...]] = {
    "username": (
        *("username", "user", "user_name", "login", "login_name", "email", "e_mail"),
        *("usuario", "nome_de_usuario", "matricula", "ra", "codigo_do_aluno"),
        *("correo", "correo_electronico", "legajo", "codigo_de_alumno"),
    ),
    "display_name": (
        *("display_name", "name", "full_name", "student", "student_name"),
        *("nome", "nome_completo", "nome_do_aluno", "nome_do_estudante", "aluno", "estudante"),
        *("nombre", "nombre_completo", "nombre_y_apellido", "apellido_y_nombre", "alumno"),
        "estudiante",
    ),
}
_COLUMN_OF = {word: column for column, words in HEADER_SYNONYMS.items() for word in words}
# What the header's refusal suggests (a few of the synonyms, as people write them).
_SHOWN = {
    "username": "username, login, usuário, matrícula, e-mail, usuario, correo",
    "display_name": "display_name, name, nome, nome completo, nombre, nombre completo",
}
_SEPARATORS = (",", ";", "\t")
# Files that are not text at all: a workbook uploaded as it is (.xlsx and .ods are
# ZIP files, .xls an OLE2 compound file).
_WORKBOOK_MAGIC = (b"PK\x03\x04", b"\xd0\xcf\x11\xe0")


@dataclass(frozen=True, slots=True)
class ClassListEntry:
    """One student of a class list: the login name (normal form) and the name as written."""

    line: int
    username: str
    display_name: str


@dataclass(frozen=True, slots=True)
class ClassList:
    """A class list read: its students and the encoding its bytes were read in.

    Attributes
    ----------
    entries : list of ClassListEntry
    encoding : {"UTF-8", "UTF-8 with BOM", "UTF-16", "Windows-1252"}
        How the bytes were read, for the teacher to see.
    """

    entries: list[ClassListEntry]
    encoding: str


def header_column(cell: str) -> str | None:
    """The column a header cell names (``"username"``, ``"display_name"``), or ``None``.

    Examples
    --------
    >>> header_column("Matrícula"), header_column(" Nome Completo "), header_column("E-mail")
    ('username', 'display_name', 'username')
    >>> header_column("turma") is None
    True
    """
    folded = re.sub(r"[\s\-]+", "_", username_form(cell).strip(" \"'"))
    return _COLUMN_OF.get(folded)


def decode_class_list(data: bytes) -> tuple[str, str]:
    """The text of a class list's bytes and the encoding read: UTF-8 first, then Windows-1252.

    Raises
    ------
    ClassListError
        For a workbook (not CSV) or bytes that are text in neither encoding
        (the line of the first bad byte).

    Examples
    --------
    >>> decode_class_list("nome\\nJoão\\n".encode("cp1252"))
    ('nome\\nJoão\\n', 'Windows-1252')
    >>> decode_class_list("nome\\nJoão\\n".encode("utf-8-sig"))
    ('nome\\nJoão\\n', 'UTF-8 with BOM')
    """
    if data.startswith(_WORKBOOK_MAGIC):
        raise ClassListError([ClassListProblem.of(1, "class_list.workbook")])
    if data.startswith(b"\xef\xbb\xbf"):
        return _decode(data[3:], "utf-8", "UTF-8 with BOM"), "UTF-8 with BOM"
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        return _decode(data, "utf-16", "UTF-16"), "UTF-16"
    if b"\x00" in data:  # UTF-16 without a BOM, or a binary file: neither is a CSV we read
        _refuse(data, data.index(b"\x00"))
    try:
        return data.decode("utf-8"), "UTF-8"
    except UnicodeDecodeError:
        pass
    return _decode(data, "cp1252", "Windows-1252"), "Windows-1252"


def _decode(data: bytes, codec: str, label: str) -> str:
    try:
        return data.decode(codec)
    except UnicodeDecodeError as exc:
        _refuse(data, exc.start)
    raise AssertionError("unreachable")  # pragma: no cover - _refuse raises


def _refuse(data: bytes, at: int) -> None:
    line = data[:at].count(b"\n") + 1
    byte = at - (data.rfind(b"\n", 0, at) + 1) + 1
    raise ClassListError([ClassListProblem.of(line, "class_list.not_text", byte=byte)])


def parse_class_list(data: bytes) -> list[ClassListEntry]:
    """Return the students of a class list, or raise with every bad line.

    :func:`read_class_list` without the encoding.

    Examples
    --------
    >>> [e.username for e in parse_class_list("username;name\\nJoão;João Silva\\n".encode())]
    ['joao']
    >>> latin = "Matrícula;Nome\\n42;Zoë Ávila\\n".encode("cp1252")
    >>> [e.display_name for e in parse_class_list(latin)]
    ['Zoë Ávila']
    """
    return read_class_list(data).entries


def read_class_list(data: bytes) -> ClassList:
    """Return the students of a class list and its encoding, or raise with every bad line.

    Raises
    ------
    ClassListError
        A file too large, a workbook, not text (the line of the first bad
        byte), a header without one login and one name column or with unknown
        ones, a line with the wrong number of cells, a bad login or display
        name, or a login name twice (case and accents do not count: ``João``
        and ``joao`` are the same person).
    """
    if len(data) > MAX_CLASS_LIST_BYTES:
        raise ClassListError(
            [ClassListProblem.of(0, "class_list.too_large", limit=MAX_CLASS_LIST_BYTES)]
        )
    text, encoding = decode_class_list(data)
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise ClassListError([ClassListProblem.of(1, "class_list.empty")])
    separator = max(_SEPARATORS, key=lines[0].count)
    rows = _rows(text, separator)
    header_cells = rows[0][1]
    columns = [header_column(cell) for cell in header_cells]
    if None in columns or sorted(c for c in columns if c) != ["display_name", "username"]:
        raise ClassListError(
            [
                ClassListProblem.of(
                    1,
                    "class_list.header",
                    columns=", ".join(repr(c) for c in header_cells),
                    logins=_SHOWN["username"],
                    names=_SHOWN["display_name"],
                )
            ]
        )
    if len(rows) - 1 > MAX_CLASS_LIST_ROWS:
        raise ClassListError(
            [ClassListProblem.of(0, "class_list.too_many", limit=MAX_CLASS_LIST_ROWS)]
        )
    where = {c: i for i, c in enumerate(columns) if c}
    return ClassList(_entries(rows[1:], len(columns), where), encoding)


def _rows(text: str, separator: str) -> list[tuple[int, list[str]]]:
    """``(physical line where the row starts, cells)``: a quoted cell may span lines."""
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=separator, strict=True)
    rows: list[tuple[int, list[str]]] = []
    try:
        start = 1
        for row in reader:
            rows.append((start, row))
            start = reader.line_num + 1
    except csv.Error as exc:
        raise ClassListError(
            [ClassListProblem.of(reader.line_num, "class_list.not_csv", reason=str(exc))]
        ) from None
    return rows


def _entries(
    rows: list[tuple[int, list[str]]], width: int, where: Mapping[str, int]
) -> list[ClassListEntry]:
    problems: list[ClassListProblem] = []
    entries: list[ClassListEntry] = []
    first_line: dict[str, int] = {}
    for number, row in rows:
        if not any(cell.strip() for cell in row):
            continue
        if len(row) != width:
            problems.append(
                ClassListProblem.of(number, "class_list.cells", cells=len(row), columns=width)
            )
            continue
        login, name = row[where["username"]], row[where["display_name"]]
        try:
            username = normalize_username(login)
        except InvalidParameterError:
            problems.append(
                ClassListProblem.of(
                    number, "class_list.username", value=repr(login), limit=MAX_USERNAME
                )
            )
            continue
        try:
            display_name = normalize_display_name(name)
        except InvalidParameterError:
            problems.append(
                ClassListProblem.of(
                    number, "class_list.display_name", value=repr(name), limit=MAX_DISPLAY_NAME
                )
            )
            continue
        if username in first_line:
            problems.append(
                ClassListProblem.of(
                    number, "class_list.duplicate", value=repr(username), first=first_line[username]
                )
            )
            continue
        first_line[username] = number
        entries.append(ClassListEntry(number, username, display_name))
    if problems:
        raise ClassListError(problems)
    if not entries:
        raise ClassListError([ClassListProblem.of(2, "class_list.no_student")])
    return entries
