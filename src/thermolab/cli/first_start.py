"""What a lab with no teacher yet prints: commands that work as printed.

The quick start runs ``.venv/bin/thermolab serve`` from a virtual environment
that is not activated, so a plain ``thermolab`` is not on PATH; and the server
holds its terminal, so the commands are typed in a second one, which opens in
the home folder, where ``.venv/bin/thermolab`` is not found either. The
commands therefore name the running program by its absolute path (plain
``thermolab`` only when that is the same program on PATH), and the lab by
absolute paths too: the data folder when it is not the per-user default (a
``$THERMOLAB_DATA_DIR`` set in the first terminal is not set in the second),
the configuration file.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from thermolab.lab.config import LabConfig

__all__ = ["command_line", "command_name", "first_start_message"]


def command_name() -> str:
    """The running ``thermolab`` as it can be typed in any terminal, in any folder.

    ``thermolab`` when the one on PATH is this program; else the program's
    absolute path (``python -m thermolab``: this interpreter's, with ``-m``).
    """
    import thermolab

    script = Path(sys.argv[0])
    package = Path(thermolab.__file__).resolve().parent
    mains = (package / "__main__.py", package / "cli" / "__main__.py")
    if script.name == "__main__.py" and script.resolve() in mains:  # python -m thermolab
        on_path = shutil.which("thermolab")
        if on_path and Path(on_path).parent == Path(sys.executable).parent:
            return "thermolab"
        return f"{shlex.quote(str(Path(sys.executable).absolute()))} -m thermolab"
    if script.name != "thermolab":  # an embedding program (tests call main() in-process)
        return "thermolab"
    found = shutil.which("thermolab")
    if found and Path(found).resolve() == script.resolve():
        return "thermolab"
    # absolute(), not resolve(): the venv's own path, which stays valid when its
    # python is a link elsewhere.
    return shlex.quote(str(script.absolute()))


def command_line(args: argparse.Namespace, config: LabConfig, *words: str) -> str:
    """``thermolab [--data-dir D] WORDS [--config F] [--database-url U]`` for this lab.

    ``WORDS`` are written as given (placeholders such as ``NAME`` and a shell
    redirection among them); the lab's own paths are absolute and quoted.
    """
    parts = [command_name()]
    if args.data_dir is not None or os.environ.get("THERMOLAB_DATA_DIR"):
        parts += ["--data-dir", shlex.quote(str(config.data_dir))]
    redirect = [w for w in words if w.startswith(">")]
    parts += [w for w in words if not w.startswith(">")]
    if args.config:
        parts += ["--config", shlex.quote(str(Path(args.config).expanduser().absolute()))]
    if args.database_url:
        parts += ["--database-url", shlex.quote(_shown_url(args.database_url))]
    return " ".join(parts + redirect)


def _shown_url(url: str) -> str:
    """A database URL without its password (the message goes to logs): ``***`` in its place."""
    from sqlalchemy.engine import make_url

    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # not a URL SQLAlchemy reads: the start refuses it before this
        return url


def first_start_message(args: argparse.Namespace, config: LabConfig) -> str:
    """The lines ``serve`` prints while the lab has no teacher: who to create, and how."""
    from thermolab.cli._words import _

    def run(*words: str) -> str:
        return f"    {command_line(args, config, *words)}"

    def say(words: str) -> str:
        return f"  {words}"

    return "\n".join(
        [
            say(_("No teacher account yet. In another terminal, create the lab's administrator")),
            say(
                _(
                    "(a teacher who also manages accounts and rigs), "
                    "then log in at the address above:"
                )
            ),
            run("user", "add", "NAME", "--role", "admin"),
            say(_("a teacher:")),
            run("user", "add", "NAME", "--role", "teacher"),
            say(_("students: a course, then its class list (a CSV with username,display_name")),
            say(_("columns; the one-time passwords go to passwords.csv, to hand out):")),
            run("course", "create", "COURSE", "--title", "TITLE", "--teacher", "NAME"),
            run("course", "import", "COURSE", "class.csv", "> passwords.csv"),
            say(_("or one student:")),
            run("user", "add", "NAME", "--role", "student"),
            say(_("(a teacher can also do this on a course's page once logged in.)")),
        ]
    )
