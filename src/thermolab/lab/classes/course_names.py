"""What a course is called and how one enrols in it: names, titles, enrolment codes.

A course's name is its handle in URLs and commands (checked here); its title
is free text; its enrolment code is read aloud in a classroom.
"""

from __future__ import annotations

import re
import secrets

__all__ = ["COURSE_NAME", "course_name", "course_title", "new_enrol_code"]

COURSE_NAME = re.compile(r"^[a-z0-9][a-z0-9._-]{0,63}$")
# No 0/O or 1/I/L: a code is read aloud in a classroom and typed from a slide.
_CODE_ALPHABET = "ABCDEFGHJKMNPQRSTUVWXYZ23456789"
_CODE_LENGTH = 10


def new_enrol_code() -> str:
    """A random enrolment code: 10 characters, about 50 bits, easy to read aloud."""
    return "".join(secrets.choice(_CODE_ALPHABET) for _ in range(_CODE_LENGTH))


def course_name(name: str) -> str:
    from thermolab.errors import InvalidParameterError

    cleaned = name.strip().lower()
    if not COURSE_NAME.fullmatch(cleaned):
        raise InvalidParameterError(
            f"course name {name!r} is not valid: use 1 to 64 letters, digits, '.', '_' or '-' "
            "(no spaces; the title may have them)"
        )
    return cleaned


def course_title(title: str) -> str:
    from thermolab.errors import InvalidParameterError

    cleaned = " ".join(title.split())
    if not 0 < len(cleaned) <= 200:
        raise InvalidParameterError("a course title must have 1 to 200 characters")
    return cleaned
