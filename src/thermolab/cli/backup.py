"""``thermolab backup FILE`` and ``thermolab restore FILE``: a lab into one archive and back.

``backup`` copies a running lab (its database, consistently, and its data
folder) into one ``.tar.gz`` with a manifest of checksums
(:mod:`thermolab.lab.operations.backup`); ``restore`` brings it back into an empty data
folder or database, refusing a damaged archive, a backup from a newer
ThermoLab, or a target that is not empty, with one line and exit status 1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from thermolab.cli._words import _, examples
from thermolab.cli.serve import add_database_options, lab_config_from_args

__all__ = ["register"]


#: The commands as they are typed (never translated); :func:`~thermolab.cli._words.examples`
#: puts the heading in the user's language.
_EXAMPLE_COMMANDS = (
    "thermolab --data-dir /srv/thermolab backup /var/backups/thermolab/lab-$(date +%F).tar.gz",
    "thermolab --data-dir /srv/thermolab-new restore /var/backups/thermolab/lab-2026-11-28.tar.gz",
    "thermolab backup lab.tar.gz --database-url postgresql+psycopg://lab@db/thermolab",
)


def register(subparsers: Any) -> None:
    """Add the ``backup`` and ``restore`` subcommands to the ``thermolab`` parser.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The subparsers of the top-level parser.
    """
    backup = subparsers.add_parser(
        "backup",
        help=_("copy the lab (database and data folder) into one archive, even while it runs"),
        description=_(
            "Copy the lab's database (consistently, while it runs) and data folder "
            "into one .tar.gz with a manifest of checksums."
        ),
        epilog=examples(*_EXAMPLE_COMMANDS),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    backup.add_argument("archive", metavar="FILE.tar.gz", help=_("the archive to write"))
    add_database_options(backup)
    backup.set_defaults(handler=_backup)

    restore = subparsers.add_parser(
        "restore",
        help=_("bring a backup back into an empty data folder or database"),
        description=_(
            "Restore a 'thermolab backup' archive into an empty data folder (and an "
            "empty database with --database-url), checking every checksum first."
        ),
        epilog=examples(*_EXAMPLE_COMMANDS),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    restore.add_argument("archive", metavar="FILE.tar.gz", help=_("the archive to read"))
    add_database_options(restore)
    restore.set_defaults(handler=_restore)


def _backup(args: argparse.Namespace) -> int:
    from thermolab.cli.serve import make_private
    from thermolab.lab.operations.backup import make_backup

    config = lab_config_from_args(args)
    make_private(config)
    manifest = make_backup(config, Path(args.archive))
    size = sum(int(f["size"]) for f in manifest.files.values())
    print(
        _(
            "backed up the lab (ThermoLab {version}, schema {revision}, "
            "{files} files, {size} bytes) into {archive}"
        ).format(
            version=manifest.version,
            revision=manifest.revision,
            files=len(manifest.files),
            size=size,
            archive=args.archive,
        )
    )
    return 0


def _restore(args: argparse.Namespace) -> int:
    from thermolab.cli import CliError
    from thermolab.cli.serve import make_private
    from thermolab.lab.operations.backup import restore_backup

    archive = Path(args.archive)
    if not archive.is_file():
        raise CliError(_("no backup at {path}").format(path=archive))
    config = lab_config_from_args(args)
    make_private(config)  # the restored files are the server user's only
    manifest = restore_backup(archive, config)
    print(
        _("restored the backup of {created} (ThermoLab {version}) into {path}").format(
            created=manifest.created, version=manifest.version, path=config.data_dir
        ),
        file=sys.stdout,
    )
    return 0
