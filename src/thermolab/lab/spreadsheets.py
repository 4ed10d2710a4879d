"""CSV files for people: the spreadsheet dialect of a language.

Every CSV the lab writes (grades, analytics, the audit log, a run's samples)
has two forms. The *machine form* — comma, decimal point, UTF-8 without a
BOM, ISO 8601 UTC instants, English column names — is what scripts read and
stays as it was. The *spreadsheet form* is what Excel or LibreOffice Calc
opens as columns with a double click in the reader's language
(:class:`SheetDialect`):

========  =========  =======  ===  ============================  ======================
language  separator  decimal  BOM  instants (reader's zone)      words
========  =========  =======  ===  ============================  ======================
pt-BR     ``;``      ``,``    yes  ``24/11/2026 14:05:09``       Portuguese
es        ``;``      ``,``    yes  ``24/11/2026 14:05:09``       Spanish
en        ``,``      ``.``    yes  ``2026-11-24 14:05:09``       English
========  =========  =======  ===  ============================  ======================

A spreadsheet in a comma-decimal locale splits columns on ``;`` (its list
separator) and reads ``0,14`` as a number; the BOM makes Excel read UTF-8
(accents intact) instead of the Windows code page. Numbers are written as
the pages show them: at most 10 significant digits (no float noise such as
``250.12623300000004``), never in scientific notation, no ``.0`` on whole
numbers, no thousands separator (which a spreadsheet could read as a decimal
mark of another locale). Column names and words (states, yes/no) come from
the server's gettext catalogue (``lab/locale``), the same one the error
sentences use; :data:`SHEET_WORDS` declares every English msgid.

The routes take the form from the query: no ``dialect`` is the machine form;
``?dialect=pt-BR&tz=America/Sao_Paulo`` the spreadsheet form
(:func:`sheet_dialect`). The browser's links pass the page's language and the
browser's time zone. Hand-written, and why: Babel formats numbers with
grouping and dates with month names, which spreadsheets do not read back, and
the :mod:`locale` module is process-wide state a server must not switch; what
is left is a few lines of :mod:`decimal` and :meth:`datetime.strftime`.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, tzinfo
from decimal import Decimal

from thermolab.errors import InvalidParameterError
from thermolab.lab.config.time_zones import is_known_zone, zone_named
from thermolab.lab.error_messages import LANGUAGES, translate

__all__ = [
    "SHEET_WORDS",
    "SheetDialect",
    "formula_safe",
    "machine_number",
    "plain_number",
    "sheet_dialect",
]

#: Every word the spreadsheet forms use, as English gettext msgids (``{name}``: a
#: value filled in). Grouped by the file that uses them.
SHEET_WORDS: tuple[str, ...] = (
    # yes/no cells
    "yes",
    "no",
    # grades
    "Course",
    "Assignment no.",
    "Assignment",
    "Login name",
    "Name",
    "State",
    "Mark",
    "Out of",
    "Late",
    "Handed in at",
    "Marked at",
    "Run",
    "Answer Ks",
    "Answer Ts",
    "Answer θ",
    "Conclusion",
    "Automatic mark",
    "Teacher's comment",
    "marked",
    "to review",
    "not handed in",
    # analytics
    "Time in control (s)",
    "Turns",
    "Runs",
    "Runs running",
    "Runs finished",
    "Runs stopped",
    "Runs interrupted",
    "Runs failed",
    "Methods",
    "{method}: runs",
    "{method}: latest run",
    "{method}: trusted",
    "Assignments set",
    "Assignments handed in",
    "Assignments late",
    "Assignments marked",
    "Mean mark (% of the maximum)",
    "Rig",
    "Title",
    "Students",
    "Failed runs",
    "Runs stopped by an interlock",
    "Rig faults",
    "Waits",
    "Median wait (s)",
    "90th percentile wait (s)",
    "Time powered (s)",
    "Power recorded since",
    # the audit log
    "No.",
    "When",
    "Who",
    "Action",
    "About",
    "From where",
    "Detail",
    # the one-time passwords of a class list (thermolab course import --dialect)
    "One-time password",
)
_WORDS = frozenset(SHEET_WORDS)
_COMMA_DECIMAL = frozenset({"pt-BR", "es"})
# OWASP's CSV injection: a text cell starting with one of these runs as a formula.
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def formula_safe(text: str) -> str:
    """Text a spreadsheet will not run as a formula (a leading ``'`` where needed).

    Examples
    --------
    >>> formula_safe("=HYPERLINK(1)"), formula_safe("Ana")
    ("'=HYPERLINK(1)", 'Ana')
    """
    return "'" + text if text.startswith(_FORMULA_START) else text


def plain_number(value: float | int, decimal: str = ".", digits: int = 10) -> str:
    """A number as a person reads it: ``digits`` significant digits, positional, no ``.0``.

    Examples
    --------
    >>> plain_number(10.0), plain_number(250.12623300000004, ","), plain_number(6.6293e-11)
    ('10', '250,126233', '0.000000000066293')
    >>> plain_number(-0.0), plain_number(1234567.0), plain_number(2 / 3, ",")
    ('0', '1234567', '0,6666666667')
    """
    if isinstance(value, int):
        return str(value)
    rounded = Decimal(f"{value:.{digits}g}")
    text = format(rounded, "f")
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    if text in ("-0", ""):
        text = "0"
    return text.replace(".", decimal)


def machine_number(value: float | int) -> str:
    """A number of a machine-form CSV: Python's shortest form of the value rounded to 12
    significant digits, so arithmetic's float noise never reaches a file.

    Twelve digits keep every figure the lab computes (the paper's tables print six)
    and drop the binary fraction's last digits; a program reads the number back.

    Examples
    --------
    >>> machine_number(250.12623300000004), machine_number(10.0), machine_number(7)
    ('250.126233', '10.0', '7')
    >>> machine_number(0.1 + 0.2), machine_number(6.6293e-11)
    ('0.3', '6.6293e-11')
    """
    if isinstance(value, int):
        return str(value)
    if not math.isfinite(value):
        return repr(float(value))
    return repr(float(f"{value:.12g}"))


@dataclass(frozen=True, slots=True)
class SheetDialect:
    """How a spreadsheet in ``language`` expects a CSV file; instants shown in ``zone``.

    Attributes
    ----------
    language : {"pt-BR", "en", "es"}
    zone : str
        An IANA time zone (``America/Sao_Paulo``), named in the time columns' headings.

    Examples
    --------
    >>> pt = SheetDialect("pt-BR", "America/Sao_Paulo")
    >>> pt.delimiter, pt.decimal, pt.cell(10.0), pt.cell(True), pt.word("marked")
    (';', ',', '10', 'sim', 'corrigida')
    >>> pt.cell(datetime(2026, 11, 24, 17, 5, 9, 123456, tzinfo=UTC))
    '24/11/2026 14:05:09'
    """

    language: str
    zone: str = "UTC"

    @property
    def decimal(self) -> str:
        """The decimal mark: ``","`` in Portuguese and Spanish, ``"."`` in English."""
        return "," if self.language in _COMMA_DECIMAL else "."

    @property
    def delimiter(self) -> str:
        """The separator: ``";"`` where the decimal mark is a comma, else ``","``."""
        return ";" if self.decimal == "," else ","

    @property
    def tz(self) -> tzinfo:
        """The time zone the instants are written in."""
        return zone_named(self.zone)

    def word(self, english: str, **params: str) -> str:
        """A word of :data:`SHEET_WORDS` in the dialect's language, its ``{names}`` filled."""
        if english not in _WORDS:
            raise KeyError(f"{english!r} is not in SHEET_WORDS")
        return translate(english, self.language).format(**params)

    def timed(self, english: str) -> str:
        """The heading of a column of instants: the word and the time zone."""
        return f"{self.word(english)} ({self.zone})"

    def number(self, value: float | int) -> str:
        """A number as :func:`plain_number` writes it, with the dialect's decimal mark."""
        return plain_number(value, self.decimal) if math.isfinite(value) else ""

    def instant(self, value: datetime) -> str:
        """An instant in the dialect's zone, to the second, as the language writes dates."""
        if value.tzinfo is None:  # the database's naive instants are UTC
            value = value.replace(tzinfo=UTC)
        local = value.astimezone(self.tz)
        pattern = "%d/%m/%Y %H:%M:%S" if self.decimal == "," else "%Y-%m-%d %H:%M:%S"
        return local.strftime(pattern)

    def cell(self, value: object) -> str:
        """Any value as a cell: empty for ``None``, words for booleans, numbers, instants, text."""
        if value is None:
            return ""
        if isinstance(value, bool):
            return self.word("yes" if value else "no")
        if isinstance(value, int | float):
            return self.number(value)
        if isinstance(value, datetime):
            return self.instant(value)
        return formula_safe(str(value))

    def lines(self, header: Sequence[str], rows: Iterable[Sequence[object]]) -> Iterator[str]:
        """The file in chunks: the BOM and the header, then rows (a thousand a chunk)."""
        out = io.StringIO()
        writer = csv.writer(out, delimiter=self.delimiter, lineterminator="\r\n")
        out.write("\ufeff")
        writer.writerow([formula_safe(h) for h in header])
        for count, row in enumerate(rows, 1):
            writer.writerow([self.cell(value) for value in row])
            if count % 1000 == 0:
                yield out.getvalue()
                out.seek(0)
                out.truncate()
        yield out.getvalue()

    def document(self, header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
        """The whole file as text (:meth:`lines` joined)."""
        return "".join(self.lines(header, rows))


def sheet_dialect(language: str | None, zone: str | None = None) -> SheetDialect | None:
    """The spreadsheet dialect a request asks for, or ``None`` for the machine form.

    Parameters
    ----------
    language : str or None
        ``pt-BR``, ``en`` or ``es`` (any case; ``pt`` is pt-BR); ``None`` or ``""``:
        the machine form.
    zone : str, optional
        An IANA time zone for the instants (default UTC).

    Raises
    ------
    InvalidParameterError
        For another language or an unknown time zone.

    Examples
    --------
    >>> sheet_dialect("pt", "America/Sao_Paulo")
    SheetDialect(language='pt-BR', zone='America/Sao_Paulo')
    >>> sheet_dialect(None) is None
    True
    """
    if not language:
        return None
    wanted = language.strip().lower()
    matches = [tag for tag in LANGUAGES if wanted in (tag.lower(), tag.lower().split("-")[0])]
    if not matches:
        raise InvalidParameterError(
            f"dialect {language!r} is not one of {', '.join(LANGUAGES)} "
            "(leave it out for the machine form)"
        )
    name = (zone or "UTC").strip() or "UTC"
    if not is_known_zone(name):
        raise InvalidParameterError(
            f"tz {zone!r} is not a known IANA time zone (like America/Sao_Paulo)"
        )
    return SheetDialect(matches[0], name)
