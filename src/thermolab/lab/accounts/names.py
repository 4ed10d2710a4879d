"""People's names: login names normalised so that they never collide, display names as written.

A **login name** is stored in one normal form, and two names that differ only
by case, by accents or by Unicode compatibility forms are the same name:
NFKC (full-width ``Ｊｏａｏ`` -> ``Joao``, ligatures split), case folded
(``ß`` -> ``ss``), then accents stripped (NFD, combining marks dropped, NFC
again: ``João`` -> ``joao``). Stripping, not keeping, the accents is the
choice: a student types her login name on any keyboard (a phone without the
accent, a lab PC with another layout) and still gets in, and ``joão`` and
``joao`` can never be two accounts. The stored name is unique
(``users.username``), so the database refuses a collision too. Letters and
digits of any script are allowed, plus ``. _ @ -``.

A **display name** is how a person is called on the pages (``João da
Silva``): NFC, trimmed, inner runs of white space made one space, 1 to 128
characters of letters, combining marks, digits, spaces and ``' . , -``
(apostrophes as in ``D'Ávila``). It is shown, never used to log in.
"""

from __future__ import annotations

import unicodedata

from thermolab.errors import InvalidParameterError

__all__ = [
    "MAX_DISPLAY_NAME",
    "MAX_USERNAME",
    "normalize_display_name",
    "normalize_username",
    "username_form",
]

MAX_USERNAME = 64
MAX_DISPLAY_NAME = 128
_USERNAME_PUNCTUATION = frozenset("._@-")
_DISPLAY_PUNCTUATION = frozenset("'.,-\u2019")


def username_form(username: str) -> str:
    """The normal form of a login name (NFKC, case folded, accents stripped), unchecked.

    Examples
    --------
    >>> username_form(" João ")
    'joao'
    >>> username_form("ＭＡＲＩＡ") == username_form("maria")
    True
    >>> username_form("Straße")
    'strasse'
    """
    folded = unicodedata.normalize("NFKC", username).casefold()
    decomposed = unicodedata.normalize("NFD", folded)
    bare = "".join(ch for ch in decomposed if not unicodedata.combining(ch))
    return unicodedata.normalize("NFC", bare).strip()


def normalize_username(username: str) -> str:
    """Return a login name in its stored form, checking it.

    Raises
    ------
    InvalidParameterError
        If it is empty, longer than 64 characters, does not start with a letter
        or digit, or has characters other than letters, digits and ``. _ @ -``.

    Examples
    --------
    >>> normalize_username(" Alice ")
    'alice'
    >>> normalize_username("JOÃO.Silva")
    'joao.silva'
    """
    name = username_form(username)
    valid = (
        0 < len(name) <= MAX_USERNAME
        and name[0].isalnum()
        and all(ch.isalnum() or ch in _USERNAME_PUNCTUATION for ch in name)
    )
    if not valid:
        raise InvalidParameterError(
            f"user name {username!r} is not valid: use 1 to {MAX_USERNAME} letters, digits, "
            "'.', '_', '@' or '-', starting with a letter or digit (no spaces; "
            "a full name with spaces is a display name)"
        )
    return name


def normalize_display_name(display_name: str) -> str:
    """Return a display name as it is stored and shown, checking it.

    Raises
    ------
    InvalidParameterError
        If it is empty, longer than 128 characters or has characters other
        than letters, digits, spaces and ``' . , -``.

    Examples
    --------
    >>> normalize_display_name("  João   da Silva ")
    'João da Silva'
    >>> normalize_display_name("Ana D'Ávila-Souza")
    "Ana D'Ávila-Souza"
    """
    name = " ".join(unicodedata.normalize("NFC", display_name).split())
    valid = 0 < len(name) <= MAX_DISPLAY_NAME and all(
        ch.isalnum()
        or ch == " "
        or ch in _DISPLAY_PUNCTUATION
        or unicodedata.category(ch).startswith("M")
        for ch in name
    )
    if not valid:
        raise InvalidParameterError(
            f"display name {display_name!r} is not valid: use 1 to {MAX_DISPLAY_NAME} letters, "
            "digits, spaces and ' . , -"
        )
    return name
