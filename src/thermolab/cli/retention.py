"""``thermolab retention apply [--dry-run]``: remove the people past the lab's retention period.

The period is the lab's setting (``[retention]`` in the configuration file,
``$THERMOLAB_RETENTION_MONTHS`` and ``$THERMOLAB_RETENTION_ACTION``, or
``--retention-months`` and ``--retention-action`` here and on ``thermolab
serve``, the later over the earlier). The server applies it daily by itself;
this command does one pass now, for a lab whose server is stopped or to see
first who would go (``--dry-run`` lists them and changes nothing). Without a
period it refuses: nothing is ever removed automatically.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from thermolab.cli._words import _, library_text
from thermolab.cli.serve import add_database_options, lab_config_from_args, make_private

if TYPE_CHECKING:
    from thermolab.lab.config import LabConfig

__all__ = ["add_retention_options", "register", "retention_line"]


def add_retention_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--retention-months`` and ``--retention-action`` (``serve`` and ``retention``)."""
    parser.add_argument(
        "--retention-months",
        type=_months,
        metavar="N",
        help=_(
            "remove the students whose courses all closed over N months ago (default: "
            "$THERMOLAB_RETENTION_MONTHS, else the configuration's [retention] months, else "
            "never)"
        ),
    )
    parser.add_argument(
        "--retention-action",
        choices=("pseudonymise", "delete"),
        help=_(
            "pseudonymise (their runs kept under a pseudonym) or delete (with their runs) "
            "(default: $THERMOLAB_RETENTION_ACTION, else the configuration's, else pseudonymise)"
        ),
    )


def retention_line(config: LabConfig) -> str:
    """What ``thermolab serve`` says at start about a retention period that is set."""
    policy = config.retention
    return _(
        "students whose courses all closed over {months} months ago are removed daily ({action})"
    ).format(months=policy.months, action=policy.action)


def register(subparsers: Any) -> None:
    """Add the ``retention`` subcommand to the ``thermolab`` parser."""
    parser = subparsers.add_parser(
        "retention",
        help=_("remove the people of courses closed longer than the retention period"),
    )
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    apply = actions.add_parser(
        "apply", help=_("remove them now (the server does it daily); --dry-run lists them")
    )
    apply.add_argument(
        "--dry-run", action="store_true", help=_("list who would be removed; change nothing")
    )
    add_retention_options(apply)
    add_database_options(apply)
    apply.set_defaults(handler=_apply)


def _months(text: str) -> int:
    from thermolab.errors import ConfigError
    from thermolab.lab.config.retention import check_months

    try:
        return check_months(int(text), "--retention-months")
    except (ValueError, ConfigError):
        raise argparse.ArgumentTypeError(
            _("expected a whole number of months from 1 to 1200, got {value}").format(
                value=repr(text)
            )
        ) from None


def _apply(args: argparse.Namespace) -> int:
    from thermolab.cli import CliError
    from thermolab.lab.accounts.security import default_password_hasher
    from thermolab.lab.audit.log import AuditLog
    from thermolab.lab.classes.retention import RetentionService
    from thermolab.lab.clock import SystemClock
    from thermolab.lab.db import Database

    config = lab_config_from_args(args)
    policy = config.retention
    if policy.months is None:
        raise CliError(
            _(
                "no retention period is set, so nobody is removed automatically; set "
                "[retention] months in the configuration, $THERMOLAB_RETENTION_MONTHS or "
                "--retention-months"
            )
        )
    for path in make_private(config):
        print(
            _("warning: tightened permissions of {path} to this user only").format(path=path),
            file=sys.stderr,
        )
    db = Database(config.database, pool_size=1, max_overflow=1)
    try:
        db.upgrade()
        clock = SystemClock()
        service = RetentionService(
            db, clock, policy, AuditLog(db, clock), default_password_hasher()
        )
        report = service.due() if args.dry_run else service.apply()
    finally:
        db.close()
    assert report.cutoff is not None  # a period is set
    before = f"{report.cutoff:%Y-%m-%d}"
    if args.dry_run:
        for person in report.due:
            print(f"{person.username}\t{person.last_closed:%Y-%m-%d}")
        print(
            _(
                "{count} students' courses all closed before {date} ({months} months ago); "
                "without --dry-run they are removed ({action})"
            ).format(
                count=len(report.due), date=before, months=policy.months, action=policy.action
            ),
            file=sys.stderr,
        )
        return 0
    print(
        _(
            "removed {count} students whose courses all closed before {date} ({action}); "
            "each removal is in the audit log"
        ).format(count=len(report.removed), date=before, action=policy.action)
    )
    for username, reason in report.skipped.items():
        print(
            "  " + _("left {name}: {reason}").format(name=username, reason=library_text(reason)),
            file=sys.stderr,
        )
    return 1 if report.skipped else 0
