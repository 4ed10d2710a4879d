"""``thermolab user``: manage the lab's accounts.

``add NAME --role student|teacher|admin``, ``list``, ``passwd NAME``, ``remove NAME``,
``admin NAME [--revoke]`` (a lab administrator is a teacher who also manages
accounts, rigs and LTI platforms; see ``thermolab.lab.accounts.policy``),
``forget NAME --runs keep|delete`` (the person's name leaves every row; their
runs stay under a pseudonym or go: :func:`thermolab.lab.accounts.personal_data.forget_person`).
Passwords are asked twice on the terminal, or read as one line from standard
input with ``--password-stdin`` (scripts: ``printf '%s\\n' "$PW" | thermolab
user add ana --role student --password-stdin``). The accounts live in the lab's
database (the data folder's SQLite file, or ``--database-url``), so this works
while the server runs.
"""

from __future__ import annotations

import argparse
import getpass
import sys
from typing import TYPE_CHECKING, Any

from thermolab.cli._words import _, examples
from thermolab.cli.serve import add_database_options, lab_config_from_args, make_private

if TYPE_CHECKING:
    from thermolab.lab.accounts.users import UserService
    from thermolab.lab.db import Database

__all__ = ["register"]

#: The commands as they are typed (never translated).
_EXAMPLES = (
    "thermolab user add root --role admin",
    "thermolab user add tina --role teacher",
    "thermolab user admin tina",
    "printf '%s\\n' \"$PASSWORD\" | thermolab user add ana --role student --password-stdin",
    "thermolab user list",
    "thermolab user passwd ana",
    "thermolab user remove ana",
    "thermolab user forget ana --runs keep",
)


def register(subparsers: Any) -> None:
    """Add the ``user`` subcommand to the ``thermolab`` parser.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The subparsers of the top-level parser.
    """
    parser = subparsers.add_parser(
        "user",
        help=_("manage the lab's accounts (add, list, passwd, remove)"),
        description=_("Manage the accounts of the lab."),
        epilog=examples(*_EXAMPLES),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    actions = parser.add_subparsers(
        dest="action", metavar="ACTION", parser_class=type(parser), required=True
    )

    add = actions.add_parser("add", help=_("create an account"))
    add.add_argument(
        "name",
        metavar="NAME",
        help=_(
            "login name (letters, digits, . _ @ -; stored without case or accents: João -> joao)"
        ),
    )
    add.add_argument(
        "--role",
        required=True,
        help=_("student, teacher or admin (a teacher who also manages accounts, rigs and LTI)"),
    )
    add.add_argument(
        "--display-name",
        metavar="TEXT",
        help=_("the name shown on the pages, as written (e.g. 'João da Silva')"),
    )
    _password_option(add)
    add_database_options(add)
    add.set_defaults(handler=_add)

    listing = actions.add_parser("list", help=_("list the accounts"))
    add_database_options(listing)
    listing.set_defaults(handler=_list)

    passwd = actions.add_parser("passwd", help=_("change a password (ends the user's logins)"))
    passwd.add_argument("name", metavar="NAME")
    _password_option(passwd)
    add_database_options(passwd)
    passwd.set_defaults(handler=_passwd)

    admin = actions.add_parser(
        "admin", help=_("make a teacher a lab administrator (or take it back with --revoke)")
    )
    admin.add_argument("name", metavar="NAME")
    admin.add_argument("--revoke", action="store_true", help=_("take the administrator role back"))
    add_database_options(admin)
    admin.set_defaults(handler=_admin)

    remove = actions.add_parser(
        "remove", help=_("remove an account with its logins, queue places and runs")
    )
    remove.add_argument("name", metavar="NAME")
    add_database_options(remove)
    remove.set_defaults(handler=_remove)

    forget = actions.add_parser(
        "forget",
        help=_(
            "remove a person for good: their name leaves every row; runs kept under a "
            "pseudonym or deleted"
        ),
    )
    forget.add_argument("name", metavar="NAME")
    forget.add_argument(
        "--runs",
        required=True,
        choices=("keep", "delete"),
        help=_(
            "keep: runs, turns and hand-ins stay for the class's statistics under a "
            "pseudonym; delete: they go with the account"
        ),
    )
    add_database_options(forget)
    forget.set_defaults(handler=_forget)


def _password_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--password-stdin",
        action="store_true",
        help=_("read the password as one line from standard input instead of asking"),
    )


def _users(args: argparse.Namespace) -> tuple[Database, UserService]:
    from thermolab.lab.accounts.security import default_password_hasher
    from thermolab.lab.accounts.users import UserService
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
    return db, UserService(db, SystemClock(), default_password_hasher())


def _read_password(args: argparse.Namespace, name: str) -> str:
    from thermolab.cli import CliError
    from thermolab.lab.accounts.security import validate_password

    if args.password_stdin:
        line = sys.stdin.readline()
        password = line.removesuffix("\n").removesuffix("\r")
        if not password:
            raise CliError(_("no password on standard input (expected one line)"))
    else:
        if not sys.stdin.isatty():
            raise CliError(
                _(
                    "standard input is not a terminal, so the password cannot be asked: "
                    "pipe it with --password-stdin"
                )
            )
        password = getpass.getpass(_("Password for {name}: ").format(name=name))
        validate_password(password, name)
        if getpass.getpass(_("Repeat the password: ")) != password:
            raise CliError(_("the two passwords differ; nothing was changed"))
    return validate_password(password, name)


def _add(args: argparse.Namespace) -> int:
    from thermolab.lab.accounts.names import normalize_display_name
    from thermolab.lab.accounts.security import normalize_username
    from thermolab.lab.accounts.users import parse_role

    name = normalize_username(args.name)
    if args.display_name is not None:
        normalize_display_name(args.display_name)  # refused before the password is asked
    admin = args.role.strip().lower() == "admin"
    role = parse_role("teacher" if admin else args.role)
    db, users = _users(args)
    try:
        password = _read_password(args, name)
        user = users.add(name, password, role, args.display_name, admin=admin)
    finally:
        db.close()
    shown = f" ({user.display_name})" if user.display_name else ""
    kind = _kind(user.role.value, user.admin)
    print(_("added {kind} {name}{shown}").format(kind=kind, name=repr(user.username), shown=shown))
    return 0


def _kind(role: str, admin: bool) -> str:
    """An account's kind in the user's language: admin, teacher or student."""
    if admin:
        return _("admin")
    return _("teacher") if role == "teacher" else _("student")


def _admin(args: argparse.Namespace) -> int:
    db, users = _users(args)
    try:
        user = users.set_admin(args.name, not args.revoke)
    finally:
        db.close()
    if user.admin:
        done = _("{name} is now a lab administrator")
    else:
        done = _("{name} is no longer a lab administrator")
    print(done.format(name=repr(user.username)))
    return 0


def _list(args: argparse.Namespace) -> int:
    db, users = _users(args)
    try:
        accounts = users.list()
    finally:
        db.close()
    if not accounts:
        from thermolab.cli.first_start import command_line

        admin = command_line(
            args, lab_config_from_args(args), "user", "add", "NAME", "--role", "admin"
        )
        print(
            _("no accounts yet; add the lab's administrator with: {command}").format(command=admin)
        )
        return 0
    width = max(8, *(len(u.username) for u in accounts))
    kinds = [_kind(user.role.value, user.admin) for user in accounts]
    role_width = max(7, *(len(kind) for kind in kinds))
    columns = _("username"), _("role"), _("created (UTC)")
    print(f"{columns[0]:<{width}}  {columns[1]:<{role_width}}  {columns[2]}")
    for user, kind in zip(accounts, kinds, strict=True):
        created = user.created_at.strftime("%Y-%m-%d %H:%M")
        print(f"{user.username:<{width}}  {kind:<{role_width}}  {created}")
    return 0


def _passwd(args: argparse.Namespace) -> int:
    db, users = _users(args)
    try:
        user = users.get(args.name)
        password = _read_password(args, user.username)
        users.set_password(user.username, password)
    finally:
        db.close()
    print(
        _("changed the password of {name}; their logins have ended").format(
            name=repr(user.username)
        )
    )
    return 0


def _remove(args: argparse.Namespace) -> int:
    db, users = _users(args)
    try:
        user = users.remove(args.name)
    finally:
        db.close()
    kind = _kind(user.role.value, False)
    print(_("removed {kind} {name}").format(kind=kind, name=repr(user.username)))
    return 0


def _forget(args: argparse.Namespace) -> int:
    import secrets

    from thermolab.cli.course_term import OPERATOR
    from thermolab.lab.accounts.personal_data import forget_person
    from thermolab.lab.accounts.security import default_password_hasher
    from thermolab.lab.audit.log import AuditLog
    from thermolab.lab.clock import SystemClock

    db, _users_unused = _users(args)
    try:
        unknown = default_password_hasher().hash(secrets.token_urlsafe(32))
        written = AuditLog(db, SystemClock()).forgotten(OPERATOR, runs=args.runs)
        pseudonym = forget_person(db, args.name, args.runs, unknown, audit=written)
    finally:
        db.close()
    if args.runs == "keep":
        kept = _("forgot {name}: their runs kept as {pseudonym}")
        print(kept.format(name=repr(args.name), pseudonym=repr(pseudonym)))
    else:
        print(_("forgot {name}: their runs deleted").format(name=repr(args.name)))
    return 0
