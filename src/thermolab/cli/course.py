"""``thermolab course``: courses and class lists from the shell.

``create NAME --title TEXT --teacher NAME``, ``list``, ``import COURSE FILE``,
``assistant COURSE NAME [--remove]`` (a teaching assistant, audited); the
end of a term's ``close``, ``reopen``, ``copy`` and ``purge-students``
(:mod:`thermolab.cli.course_term`).
An import adds or updates the students of a CSV class list (a login and a
name column, headed in English, Portuguese or Spanish: ``username;display_name``,
``matrícula;nome``, ``usuario;nombre``; UTF-8 or Windows-1252) all or nothing;
a bad file is one line naming each bad line, exit 1, and nothing changes. The
new accounts' one-time passwords are printed once, as CSV on standard output
(``username,password``), so they can be redirected to a file and handed out;
``--dialect pt-BR`` (or ``es``, ``en``) writes them for a spreadsheet in that
language.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from thermolab.cli._words import _, examples
from thermolab.cli.serve import add_database_options, lab_config_from_args, make_private

if TYPE_CHECKING:
    from thermolab.lab.classes.courses import CourseService
    from thermolab.lab.db import Database

__all__ = ["register"]


def _examples() -> str:
    """The ``--help`` epilog: the commands as they are typed, the words around them translated."""
    commands = (
        'thermolab course create ctrl1 --title "Controle I" --teacher tina',
        "thermolab course import ctrl1 turma.csv > passwords.csv",
        "thermolab course import ctrl1 turma.csv --dialect pt-BR > senhas.csv",
        "thermolab course list",
        "thermolab course assistant ctrl1 rafa            # "
        + _("rafa assists ctrl1 (reads, changes nothing)"),
        "thermolab course assistant ctrl1 rafa --remove",
        "thermolab course close ctrl1",
        "thermolab course copy ctrl1 ctrl1-2027-1 --starts 2027-03-01",
        "thermolab course purge-students ctrl1            # " + _("who would go (nothing changes)"),
        "thermolab course purge-students ctrl1 --yes      # "
        + _("remove them; runs kept under a pseudonym"),
    )
    return examples(*commands)


def register(subparsers: Any) -> None:
    """Add the ``course`` subcommand to the ``thermolab`` parser."""
    parser = subparsers.add_parser(
        "course",
        help=_(
            "manage courses, class lists and the end of a term (create, list, import, "
            "assistant, close, reopen, copy, purge-students)"
        ),
        description=_("Manage the lab's courses and their students."),
        epilog=_examples(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    actions = parser.add_subparsers(
        dest="action", metavar="ACTION", parser_class=type(parser), required=True
    )
    create = actions.add_parser("create", help=_("create a course"))
    create.add_argument("name", metavar="NAME", help=_("short name: letters, digits, . _ -"))
    create.add_argument("--title", required=True, help=_("the title shown on the pages"))
    create.add_argument("--teacher", required=True, help=_("the login name of its first teacher"))
    add_database_options(create)
    create.set_defaults(handler=_create)

    listing = actions.add_parser("list", help=_("list the courses with their enrolment codes"))
    add_database_options(listing)
    listing.set_defaults(handler=_list)

    load = actions.add_parser(
        "import", help=_("add or update a course's students from a CSV class list")
    )
    load.add_argument("course", metavar="COURSE")
    load.add_argument(
        "--dialect",
        choices=("pt-BR", "es", "en"),
        help=_(
            "write the one-time passwords for a spreadsheet in this language (pt-BR and es: "
            "';' separated, with a BOM and translated headings); default: plain CSV"
        ),
    )
    load.add_argument(
        "file",
        metavar="FILE",
        type=Path,
        help=_("CSV: username,display_name (or matrícula;nome, usuario;nombre)"),
    )
    add_database_options(load)
    load.set_defaults(handler=_import)

    helper = actions.add_parser(
        "assistant", help=_("make someone a teaching assistant of a course (or --remove them)")
    )
    helper.add_argument("course", metavar="COURSE")
    helper.add_argument("username", metavar="NAME", help=_("the login name of an existing account"))
    helper.add_argument("--remove", action="store_true", help=_("take the assistant's place away"))
    add_database_options(helper)
    helper.set_defaults(handler=_assistant)

    from thermolab.cli.course_term import add_actions

    add_actions(actions)


def _courses(args: argparse.Namespace) -> tuple[Database, CourseService]:
    from thermolab.lab.accounts.security import default_password_hasher
    from thermolab.lab.classes.courses import CourseService
    from thermolab.lab.clock import SystemClock
    from thermolab.lab.db import Database

    config = lab_config_from_args(args)
    for path in make_private(config):
        print(
            _("warning: tightened permissions of {path} to this user only").format(path=path),
            file=sys.stderr,
        )
    db = Database(config.database, pool_size=1, max_overflow=1)
    db.upgrade()
    return db, CourseService(db, SystemClock(), default_password_hasher())


def _create(args: argparse.Namespace) -> int:
    db, courses = _courses(args)
    try:
        course = courses.create(args.name, args.title, args.teacher)
    finally:
        db.close()
    print(
        _("created course {name} ({title}); enrolment code {code}").format(
            name=repr(course.name), title=course.title, code=course.enrol_code
        )
    )
    return 0


def _list(args: argparse.Namespace) -> int:
    db, courses = _courses(args)
    try:
        found = courses.list()
    finally:
        db.close()
    if not found:
        from thermolab.cli.first_start import command_line

        create = ("course", "create", "NAME", "--title", "T", "--teacher", "T")
        command = command_line(args, lab_config_from_args(args), *create)
        print(_("no courses yet; create one with: {command}").format(command=command))
    for course in found:
        rigs = ", ".join(course.rigs) or _("all rigs")
        print(f"{course.name}\t{course.enrol_code}\t{rigs}\t{course.title}")
    return 0


def _import(args: argparse.Namespace) -> int:
    from thermolab.cli import CliError
    from thermolab.lab.classes.class_list import MAX_CLASS_LIST_BYTES

    path: Path = args.file
    try:
        with path.open("rb") as source:
            data = source.read(MAX_CLASS_LIST_BYTES + 1)
    except OSError as exc:
        raise CliError(
            _("cannot read {path}: {reason}").format(path=path, reason=exc.strerror or exc)
        ) from None
    db, courses = _courses(args)
    try:
        report = courses.import_class_list(args.course, data)
    finally:
        db.close()
    words = _(
        "{course}: {created} created, {updated} updated, {unchanged} unchanged (read as {encoding})"
    ).format(
        course=args.course,
        created=len(report.created),
        updated=len(report.updated),
        unchanged=len(report.unchanged),
        encoding=report.encoding,
    )
    print(words, file=sys.stderr)
    if report.created:
        print(
            _("one-time passwords (shown once; each must be changed at first login):"),
            file=sys.stderr,
        )
        if args.dialect:
            from thermolab.lab.spreadsheets import SheetDialect

            sheet = SheetDialect(args.dialect)
            header = [sheet.word("Login name"), sheet.word("One-time password")]
            sys.stdout.write(sheet.document(header, report.created.items()))
            return 0
        writer = csv.writer(sys.stdout, lineterminator="\n")
        writer.writerow(["username", "password"])
        for username, password in report.created.items():
            writer.writerow([username, password])
    return 0


def _assistant(args: argparse.Namespace) -> int:
    from thermolab.cli.course_term import OPERATOR
    from thermolab.lab.audit.log import AuditAction, AuditLog
    from thermolab.lab.classes.assistants import AssistantService
    from thermolab.lab.clock import SystemClock

    db, _courses_unused = _courses(args)
    clock = SystemClock()
    try:
        assistants = AssistantService(db, clock)
        if args.remove:
            name = assistants.remove(args.course, args.username)
            action = AuditAction.ASSISTANT_REMOVED
        else:
            name = assistants.add(args.course, args.username)
            action = AuditAction.ASSISTANT_ADDED
        AuditLog(db, clock).record(OPERATOR, action, args.course, detail={"username": name})
    finally:
        db.close()
    if args.remove:
        done = _("{name} no longer assists course {course}")
    else:
        done = _("{name} assists course {course}")
    print(done.format(name=name, course=repr(args.course)))
    return 0
