"""The ``thermolab`` command line.

Each subcommand lives in a module of its own that exposes ``register(subparsers)``;
the module adds its parser and sets ``handler`` to a function taking the parsed
arguments and returning the exit status; a module whose name starts with ``_``
is a part of one or more subcommands (``_settings``, ``_run_args``,
``_run_report``), not a subcommand. Heavy imports (NumPy, Numba, the server)
happen inside the handlers so that ``thermolab --help`` stays instant.

Every error a user can cause ends as one line on standard error and a non-zero
exit status, never a traceback: :class:`~thermolab.errors.ThermoLabError` and
:class:`CliError` give status 1 (2 for usage errors, as argparse does), an
interrupted command 130, and anything unexpected status 70 with a one-line
"internal error" message (``THERMOLAB_DEBUG=1`` shows the traceback).
In Portuguese or Spanish (``LANG=pt_BR.UTF-8``, ``LANGUAGE=es``) the line of a
:class:`~thermolab.errors.ThermoLabError` starts with the sentence of its stable
code in that language (``thermolab.lab.error_messages``), the precise English
reason following in parentheses.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Callable, Sequence

from thermolab import __version__
from thermolab.errors import (
    ClassListError,
    CourseNameTakenError,
    NameTakenError,
    PasswordRejectedError,
    ThermoLabError,
)

__all__ = ["CliError", "main"]

# Modules that contribute a subcommand, in the order ``--help`` lists them. A
# module that does not exist yet is skipped, so the layers can land one by one.
_SUBCOMMAND_MODULES = (
    "agent",
    "backup",
    "course",
    "identify",
    "reproduce",
    "retention",
    "run",
    "serve",
    "user",
)


class CliError(Exception):
    """An error to report as one line, with the exit status to use."""

    def __init__(self, message: str, status: int = 1) -> None:
        super().__init__(message)
        self.status = status


Handler = Callable[[argparse.Namespace], int]


class _Parser(argparse.ArgumentParser):
    """An argparse parser whose errors are one line and exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        from thermolab.cli._words import _

        said = _("{prog}: {message} (see '{prog} --help')").format(prog=self.prog, message=message)
        raise CliError(said, status=2)


def build_parser() -> argparse.ArgumentParser:
    """Build the full ``thermolab`` argument parser."""
    from thermolab.cli._words import _

    parser = _Parser(
        prog="thermolab",
        description=_("ThermoLab: identify the model of a temperature control system."),
    )
    parser.add_argument(
        "--version",
        action="version",
        version=f"thermolab {__version__}",
        help=_("show the program's version and exit"),
    )
    parser.add_argument(
        "--data-dir",
        default=None,
        help=_(
            "folder for the lab's database and records (default: a per-user folder, "
            "or $THERMOLAB_DATA_DIR)"
        ),
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in _SUBCOMMAND_MODULES:
        try:
            module = importlib.import_module(f"thermolab.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"thermolab.cli.{name}":
                continue
            raise
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return its exit status."""
    from thermolab.cli._words import speaking_argparse

    try:
        with speaking_argparse():
            parser = build_parser()
            args = parser.parse_args(argv)
        handler: Handler | None = getattr(args, "handler", None)
        if handler is None:
            parser.print_help(sys.stderr)
            return 2
        return handler(args)
    except CliError as exc:
        print(f"{_error_prefix()}: {exc}", file=sys.stderr)
        return exc.status
    except ThermoLabError as exc:
        print(_error_line(exc), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        from thermolab.cli._words import _

        print(_("interrupted"), file=sys.stderr)
        return 130
    except BrokenPipeError:
        # Output piped into `head` and the like: not an error worth a message.
        return 0
    except Exception as exc:
        if os.environ.get("THERMOLAB_DEBUG"):
            raise
        from thermolab.cli._words import _

        said = _("internal error: {kind}: {error} (set THERMOLAB_DEBUG=1 for details)")
        print(said.format(kind=type(exc).__name__, error=exc), file=sys.stderr)
        return 70


def _error_prefix() -> str:
    """``error`` in the user's language."""
    from thermolab.lab.error_messages import language_from_environment, translate

    return translate("error", language_from_environment(os.environ))


def _error_line(exc: ThermoLabError) -> str:
    from thermolab.lab.error_messages import language_from_environment, translate

    language = language_from_environment(os.environ)
    if language == "en":
        return f"error: {exc}"
    # Imported only here: the error table brings the server's modules.
    from thermolab.lab.error_messages import error_message
    from thermolab.lab.http.errors import fault_of

    sentence = error_message(fault_of(exc).code, language)
    detail = str(exc)
    if isinstance(
        exc, ClassListError | PasswordRejectedError | NameTakenError | CourseNameTakenError
    ):
        # A class list's problems, a password's refusal and a taken name have sentences of
        # their own in the catalogue.
        detail = exc.describe(lambda text: translate(text, language))
    else:
        # A sentence of the numerical libraries (no excitation, no step, ...) as the
        # browser says it; any other detail as the library wrote it.
        from thermolab.web.library_words import library_sentence

        detail = library_sentence(detail, language)
    return f"{translate('error', language)}: {sentence} ({detail})"


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
