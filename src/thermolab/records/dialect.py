"""How a record file was written: separator, decimal mark, encoding."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Dialect"]


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
