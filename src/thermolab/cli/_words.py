"""The command line's words in the user's language (``LANG=pt_BR.UTF-8``, ``LANGUAGE=es``).

Every sentence the command line prints, every ``--help`` text and argparse's own
words are written in English in the code, inside ``_()``, as gettext does:
``_("removed {kind} {name}").format(...)``. That English is the msgid; Babel's
extractor finds each one (``tests/lab/test_error_messages.py`` checks that the
lab's catalogues, ``thermolab/lab/locale``, hold every one and no other) and the
catalogues translate it; a msgid without a translation stays English. What the
lines name (commands, options, paths, file names, user names, a CSV's columns)
is never translated: a command printed in Portuguese still works as printed.

argparse says its own words (``usage:``, ``options``, "the following arguments
are required: …") through the ``gettext`` module's global domain, which has no
catalogue of ours; :func:`speaking_argparse` hands them to :func:`_` while the
command line parses its arguments.
"""

from __future__ import annotations

import argparse
import contextlib
import os
from collections.abc import Iterator

__all__ = [
    "ARGPARSE_WORDS",
    "_",
    "any_words",
    "cli_language",
    "decimal",
    "examples",
    "in_language",
    "library_text",
    "speaking_argparse",
]

#: argparse's own words that a user of ``thermolab`` can meet (Python 3.11's msgids;
#: another Python's that differ stay English). The catalogues translate these too.
ARGPARSE_WORDS = (
    "usage: ",
    "positional arguments",
    "options",
    "show this help message and exit",
    "argument %(argument_name)s: %(message)s",
    "can't open '%(filename)s': %(error)s",
    "unrecognized arguments: %s",
    "not allowed with argument %s",
    "ignored explicit argument %r",
    "the following arguments are required: %s",
    "one of the arguments %s is required",
    "expected one argument",
    "expected at most one argument",
    "expected at least one argument",
    "expected %s argument",
    "expected %s arguments",
    "ambiguous option: %(option)s could match %(matches)s",
    "invalid %(type)s value: %(value)r",
    "invalid choice: %(value)r (choose from %(choices)s)",
    "unknown parser %(parser_name)r (choices: %(choices)s)",
)


def cli_language() -> str:
    """The language of this process's user, from the POSIX locale variables."""
    from thermolab.lab.error_messages import language_from_environment

    return language_from_environment(os.environ)


def _(message: str) -> str:
    """``message`` (an English msgid) in the user's language."""
    from thermolab.lab.error_messages import translate

    return translate(message, cli_language())


def in_language(message: str, language: str) -> str:
    """``message`` in ``language`` (a test or a caller that knows the reader's language).

    Examples
    --------
    >>> in_language("interrupted", "pt-BR"), in_language("interrupted", "es")
    ('interrompido', 'interrumpido')
    """
    from thermolab.lab.error_messages import translate

    return translate(message, language)


def examples(*commands: str) -> str:
    """A ``--help`` epilog: the heading in the user's language, then each command as it is
    typed, indented (a continuation line given as a command of its own keeps its indent).
    A comment after a command is the caller's ``_()``: the commands are never translated."""
    return _("examples:") + "\n" + "".join(f"  {command}\n" for command in commands)


def _ngettext(singular: str, plural: str, n: int) -> str:
    return _(singular if n == 1 else plural)


@contextlib.contextmanager
def speaking_argparse() -> Iterator[None]:
    """argparse's own words through :func:`_` while the block runs.

    argparse looks its words up at the moment it says them (``argparse._``,
    ``argparse.ngettext``, bound from ``gettext``); they are ours inside the block
    and gettext's again after it.
    """
    saved = argparse._, argparse.ngettext  # type: ignore[attr-defined]
    argparse._, argparse.ngettext = _, _ngettext  # type: ignore[attr-defined]
    try:
        yield
    finally:
        argparse._, argparse.ngettext = saved  # type: ignore[attr-defined]


def library_text(text: str) -> str:
    """A sentence of the numerical libraries (an identification warning or reason, a
    closed loop's note) in the user's language, as the browser says it; any other
    text as written."""
    language = cli_language()
    if language == "en":
        return text
    from thermolab.web.library_words import library_sentence

    return library_sentence(text, language)


def any_words(text: str) -> str:
    """``text`` in the user's language, whatever it is: a msgid declared by a library
    function that takes a translator (``Table1Result.format(say=...)``, whose words the
    catalogue test extracts there) or a sentence of the numerical libraries."""
    return library_text(_(text))


def decimal(text: str) -> str:
    """The figures of ``text`` with the user's decimal mark (``0.14`` -> ``0,14`` in
    pt-BR and es); their digits as written. For a report's values, never for a path,
    a command or output meant for a program (``--json``)."""
    language = cli_language()
    if language == "en":
        return text
    from thermolab.web.library_words import local_figures

    return local_figures(text, language)
