"""``thermolab agent`` (on a rig host) and ``thermolab agent-secret`` (on the lab).

``thermolab agent --lab wss://LAB:PORT --rig ID --spec SPEC --secret-file F``
opens the rig (``SPEC`` as in the lab's file: ``sim:tclab``, ``tclab:/dev/ttyACM0``),
keeps every sample in ``--outbox`` (a SQLite file) until the lab has it,
and dials the lab over a WebSocket (TLS with ``--ca``); nothing listens on
the rig host. It redials by itself; SIGINT/SIGTERM leave the rig safe.

``thermolab agent-secret RIG`` (where the lab's database is) issues the rig's
secret, or rotates it: it is printed once and stored only hashed.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import os
import signal
import sys
from pathlib import Path
from typing import Any

from thermolab.cli._words import _, examples
from thermolab.cli.serve import add_database_options, lab_config_from_args

__all__ = ["register"]


def _examples() -> str:
    """The ``--help`` epilog: the commands as they are typed, the words around them translated."""
    commands = (
        "thermolab agent-secret box1 --config lab.toml > box1.secret     # " + _("on the lab"),
        "thermolab agent --lab wss://lab.example:8443 --rig box1 --spec tclab \\",
        "    --secret-file box1.secret --ca lab-ca.pem                   # " + _("on the rig host"),
    )
    return examples(*commands)


def register(subparsers: Any) -> None:
    """Add ``agent`` and ``agent-secret`` to the ``thermolab`` parser."""
    agent = subparsers.add_parser(
        "agent",
        help=_("serve one rig from its host, dialling the lab (remote rigs)"),
        description=_(
            "Own a rig, its runner and interlocks on this host, and connect out to "
            "the lab that uses it."
        ),
        epilog=_examples(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    agent.add_argument(
        "--lab",
        required=True,
        action="append",
        metavar="URL",
        help=_("the lab: wss://HOST:PORT (repeat for each web worker of a fleet)"),
    )
    agent.add_argument(
        "--rig", required=True, metavar="ID", help=_("the rig's id in the lab's file")
    )
    agent.add_argument(
        "--spec", required=True, metavar="SPEC", help=_("what the rig is (sim:tclab, tclab:PORT)")
    )
    agent.add_argument(
        "--secret-file",
        required=True,
        metavar="FILE",
        help=_("the rig's secret (thermolab agent-secret)"),
    )
    agent.add_argument("--ca", metavar="FILE.pem", help=_("CA certificate(s) to trust for the lab"))
    agent.add_argument(
        "--outbox",
        metavar="FILE",
        help=_("the durable sample outbox (default: in the data folder)"),
    )
    agent.add_argument(
        "--speedup",
        type=float,
        default=1.0,
        metavar="X",
        help=_(
            "twins only: X times real time (the host's own: the lab's twin_speedup setting "
            "is for the twins the lab runs)"
        ),
    )
    agent.add_argument(
        "--ping", type=float, default=1.0, metavar="S", help=_("seconds between link checks (1)")
    )
    agent.set_defaults(handler=_agent)

    issue = subparsers.add_parser(
        "agent-secret",
        help=_("issue or rotate a remote rig's secret (on the lab)"),
        description=_("Issue a remote rig's secret, or rotate it: printed once, stored hashed."),
    )
    issue.add_argument(
        "rig", metavar="RIG", help=_("the rig's id (agent = true in the lab's file)")
    )
    add_database_options(issue)
    issue.set_defaults(handler=_issue)


def _issue(args: argparse.Namespace) -> int:
    from thermolab.lab.agents import issue_secret
    from thermolab.lab.clock import SystemClock
    from thermolab.lab.db import Database

    config = lab_config_from_args(args)
    db = Database(config.database, pool_size=1, max_overflow=1)
    try:
        db.upgrade()
        print(issue_secret(db, config, SystemClock(), args.rig))
    finally:
        db.close()
    return 0


def _agent(args: argparse.Namespace) -> int:
    from thermolab.agent import AgentLink, LinkSettings, Outbox, RigHost
    from thermolab.cli import CliError
    from thermolab.rigs import RigSpec, make_clock

    for lab in args.lab:
        if not (lab.startswith("wss://") or lab.startswith("ws://")):
            raise CliError(_("--lab {url}: use wss://HOST:PORT").format(url=repr(lab)), status=2)
    try:
        secret = Path(args.secret_file).read_text().strip()
    except OSError as exc:
        raise CliError(
            _("cannot read --secret-file {path}: {reason}").format(
                path=args.secret_file, reason=exc.strerror
            )
        ) from None
    spec = RigSpec.parse(args.spec)
    outbox_path = Path(args.outbox) if args.outbox else _default_outbox(args)
    outbox_path.parent.mkdir(parents=True, exist_ok=True)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    speedup = args.speedup if spec.simulated else 1.0
    rig = spec.open(clock=make_clock(speedup))
    outbox = Outbox(outbox_path)
    url, *others = [lab.rstrip("/") + "/api/agents/link" for lab in args.lab]
    settings = LinkSettings(
        url=url,
        others=tuple(others),
        rig=args.rig,
        secret=secret,
        spec=args.spec,
        cafile=args.ca,
        ping=args.ping,
        ping_timeout=max(2 * args.ping, 2.0),
        speedup=speedup,
    )
    host = RigHost(rig, outbox)
    link = AgentLink(host, settings)
    host.on_outbox = link.wake
    print(
        _("thermolab agent: rig {rig} ({spec}) -> {url}").format(
            rig=args.rig, spec=args.spec, url=url
        ),
        file=sys.stderr,
    )
    try:
        asyncio.run(_until_signal(link))
    finally:
        host.close()
        outbox.close()
    return 0


async def _until_signal(link: Any) -> None:
    loop = asyncio.get_running_loop()
    task = asyncio.create_task(link.run())
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, task.cancel)
    with contextlib.suppress(asyncio.CancelledError):  # SIGINT/SIGTERM: the host closes the rig
        await task


def _default_outbox(args: argparse.Namespace) -> Path:
    from thermolab.lab.config import resolve_data_dir  # only a path helper

    base = resolve_data_dir(getattr(args, "data_dir", None) or os.environ.get("THERMOLAB_DATA_DIR"))
    return base / f"agent-{args.rig}.sqlite3"
