"""Courses and people (issue #10): names taken, closed courses, hand-ins, class lists, passwords.

Each refusal's sentence is declared here by stable code (:data:`TAKEN_NAMES`,
:data:`CLASS_LIST_PROBLEMS`, :data:`PASSWORD_PROBLEMS`): the gettext msgids
``lab/locale`` translates.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

from thermolab.errors.base import AccessDeniedError, ConflictError, InvalidParameterError

__all__ = [
    "CLASS_LIST_PROBLEMS",
    "PASSWORD_PROBLEMS",
    "TAKEN_NAMES",
    "ClassListError",
    "ClassListProblem",
    "CourseClosedError",
    "CourseNameTakenError",
    "HandInRefusedError",
    "NameTakenError",
    "PasswordChangeRequiredError",
    "PasswordRejectedError",
    "WrongEnrolCodeError",
]


#: A name already taken, by stable code: an English sentence with ``{name}``, the
#: gettext msgid that ``lab/locale`` translates (the command line's detail).
TAKEN_NAMES: Mapping[str, str] = {
    "taken.user": "user {name} already exists",
    "taken.user_choose": "user {name} already exists; choose another login name",
    "taken.course": "course {name} already exists",
    "taken.course_choose": "course {name} already exists; choose another name",
}


class _TakenError(ConflictError):
    """A name already taken: ``sentence`` (a key of ``TAKEN_NAMES``) and the ``name``."""

    def __init__(self, sentence: str, name: str) -> None:
        if sentence not in TAKEN_NAMES:
            raise KeyError(sentence)
        self.sentence = sentence
        self.name = name
        super().__init__(self.describe())

    def __reduce__(self) -> tuple[type[_TakenError], tuple[str, str]]:
        return type(self), (self.sentence, self.name)

    def describe(self, translate: Callable[[str], str] = str) -> str:
        """The refusal with its sentence passed through ``translate`` (a gettext function)."""
        return translate(TAKEN_NAMES[self.sentence]).format(name=repr(self.name))


class NameTakenError(_TakenError):
    """A login name that someone already has.

    Examples
    --------
    >>> str(NameTakenError("taken.user", "ana"))
    "user 'ana' already exists"
    """


class CourseNameTakenError(_TakenError):
    """A course name that another course already has."""


class CourseClosedError(ConflictError):
    """The course is closed for the term: it is read and exported, never changed."""


class HandInRefusedError(ConflictError):
    """A run that cannot be handed in for an assignment; ``case`` (``handin_*``) says why."""

    def __init__(self, message: str, case: str) -> None:
        if not case.startswith("handin_"):
            raise ValueError(f"no hand-in refusal {case!r}")
        super().__init__(message, case=case)


#: What can be wrong with a class list, by stable code: an English sentence with
#: named ``{placeholders}``, the gettext msgid that ``lab/locale`` translates, so a
#: problem reaches the page (``error.<code>`` in the browser's catalogue) and the
#: command line in the reader's language. ``class_list.line`` frames one problem
#: and ``class_list.not_imported`` the whole list.
CLASS_LIST_PROBLEMS: Mapping[str, str] = {
    "class_list.not_imported": "the class list was not imported (nothing changed): {problems}",
    "class_list.line": "line {line}: {reason}",
    "class_list.more": "and {count} more",
    "class_list.too_large": "the file is larger than {limit} bytes",
    "class_list.workbook": (
        "the file is a spreadsheet workbook, not CSV text; in the spreadsheet choose "
        "'Save as' > 'CSV' and upload that file"
    ),
    "class_list.not_text": (
        "the file is not text in UTF-8 or Windows-1252 (byte {byte} of the line); save it as "
        "'CSV UTF-8' and upload it again"
    ),
    "class_list.empty": "the file is empty; the first line must be the header",
    "class_list.not_csv": "not readable as CSV ({reason})",
    "class_list.header": (
        "the header has columns {columns}; it must have one login column ({logins}) and "
        "one name column ({names})"
    ),
    "class_list.too_many": "more than {limit} students in one list",
    "class_list.cells": "{cells} cells where the header has {columns}",
    "class_list.username": (
        "user name {value} is not valid: use 1 to {limit} letters, digits, '.', '_', '@' or '-', "
        "starting with a letter or digit (no spaces; a full name with spaces is a display name)"
    ),
    "class_list.display_name": (
        "display name {value} is not valid: use 1 to {limit} letters, digits, spaces and ' . , -"
    ),
    "class_list.duplicate": "login name {value} is already on line {first}",
    "class_list.no_student": "the list has a header but no student",
    "class_list.teacher": "{value} is a teacher's account, not a student's",
}


@dataclass(frozen=True, slots=True)
class ClassListProblem:
    """One bad line of a class list: where, which problem (a key of ``CLASS_LIST_PROBLEMS``), and
    the values its sentence names.

    Examples
    --------
    >>> ClassListProblem.of(3, "class_list.duplicate", value="'ana'", first=2).reason
    "login name 'ana' is already on line 2"
    """

    line: int
    code: str
    params: Mapping[str, str | int] = field(default_factory=dict)

    @classmethod
    def of(cls, line: int, code: str, **params: str | int) -> ClassListProblem:
        """The problem ``code`` on ``line``, with its sentence's values."""
        if code not in CLASS_LIST_PROBLEMS:
            raise KeyError(code)
        return cls(line, code, params)

    def sentence(self, translate: Callable[[str], str] = str) -> str:
        """The problem in words, each sentence passed through ``translate`` (English by default)."""
        return translate(CLASS_LIST_PROBLEMS[self.code]).format(**self.params)

    @property
    def reason(self) -> str:
        """The problem in English."""
        return self.sentence()


class ClassListError(InvalidParameterError):
    """A class list (CSV) with bad lines; ``problems`` holds a :class:`ClassListProblem` for each.

    The message lists every bad line, so the CLI's one line and the API's
    ``detail`` say the same; nothing was changed. :meth:`describe` says it in
    another language.
    """

    def __init__(self, problems: Iterable[ClassListProblem]) -> None:
        self.problems = list(problems)
        super().__init__(self.describe())

    def describe(self, translate: Callable[[str], str] = str) -> str:
        """The message with every sentence passed through ``translate`` (a gettext function)."""

        def say(code: str, **params: str | int) -> str:
            return translate(CLASS_LIST_PROBLEMS[code]).format(**params)

        listed = [
            say("class_list.line", line=p.line, reason=p.sentence(translate))
            for p in self.problems[:20]
        ]
        if len(self.problems) > 20:
            listed.append(say("class_list.more", count=len(self.problems) - 20))
        return say("class_list.not_imported", problems="; ".join(listed))


class WrongEnrolCodeError(AccessDeniedError):
    """No course has this enrolment code (mistyped, or rotated by the teacher)."""


class PasswordChangeRequiredError(AccessDeniedError):
    """The account holds a temporary password: it must be changed before anything else."""


#: Why a new password is refused, by stable code: an English sentence with named
#: ``{placeholders}``, the gettext msgid ``lab/locale`` translates, so the refusal
#: reaches the command line and the page in the reader's language.
PASSWORD_PROBLEMS: Mapping[str, str] = {
    "password.too_short": "password too short: at least {limit} characters are needed",
    "password.too_long": "password too long: at most {limit} characters are allowed",
    "password.blank": "the password may not be only whitespace",
    "password.user_name": "the password may not be the user name or a variant of it",
    "password.breached": "this password is in a list of breached passwords; choose another",
    "password.guessable": (
        "this password is too easy to guess (a keyboard row, a sequence, a repeated "
        "character or the lab's name, with little else); choose another"
    ),
}


class PasswordRejectedError(InvalidParameterError):
    """A new password the lab refuses: ``problem`` (a key of ``PASSWORD_PROBLEMS``) and its values.

    Examples
    --------
    >>> str(PasswordRejectedError("password.too_short", limit=12))
    'password too short: at least 12 characters are needed'
    """

    def __init__(self, problem: str, **params: str | int) -> None:
        if problem not in PASSWORD_PROBLEMS:
            raise KeyError(problem)
        self.problem = problem
        self.params: Mapping[str, str | int] = dict(params)
        super().__init__(self.describe())

    def describe(self, translate: Callable[[str], str] = str) -> str:
        """The refusal with its sentence passed through ``translate`` (a gettext function)."""
        return translate(PASSWORD_PROBLEMS[self.problem]).format(**self.params)
