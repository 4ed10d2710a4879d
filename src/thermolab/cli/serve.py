"""``thermolab serve``: run the remote laboratory.

With no options it serves one digital twin (at
:data:`~thermolab.lab.config.model.QUICK_START_SPEEDUP` times real time) on
http://127.0.0.1:8000 with a SQLite database in the data folder
(``--data-dir``, ``$THERMOLAB_DATA_DIR`` or a per-user folder): nothing else
to install. ``--config FILE.toml`` declares
more rigs and the access policy (see :mod:`thermolab.lab.config`);
``--database-url`` uses PostgreSQL instead.

The HTTP server and its limits (request heads, slow clients, frames,
connections) are :mod:`thermolab.cli.http_server`'s. Files: the process's
umask is 077, so the data folder, the SQLite database (and its journal) and
the run records are the server user's only (0700/0600); looser modes found
at start are tightened, with a warning.
"""

from __future__ import annotations

import argparse
import os
import socket
import stat
import sys
import threading
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from thermolab.cli._words import _, examples
from thermolab.cli.http_server import CONNECTION_LIMIT, run_server

if TYPE_CHECKING:
    from thermolab.lab.config import LabConfig
    from thermolab.lab.operations.collector import CollectorPolicy

__all__ = [
    "add_database_options",
    "lab_config_from_args",
    "make_private",
    "register",
]


def _examples() -> str:
    """The ``--help`` epilog: the commands as they are typed, the words around them translated."""
    commands = (
        "thermolab serve",
        "thermolab --data-dir /srv/thermolab serve --host 0.0.0.0 --config lab.toml",
        "thermolab serve --database-url postgresql+psycopg://lab@localhost/thermolab",
        "thermolab serve --speedup 50        # " + _("saves 50 as every twin's speed-up (demos)"),
    )
    return examples(*commands)


def add_database_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--config`` and ``--database-url`` (shared by ``serve`` and ``user``)."""
    parser.add_argument(
        "--config",
        metavar="FILE.toml",
        help=_("lab configuration: rigs, limits, access policy, database (default: one twin)"),
    )
    parser.add_argument(
        "--database-url",
        metavar="URL",
        help=_(
            "database to use instead of SQLite in the data folder "
            "(e.g. postgresql+psycopg://USER@HOST/DB)"
        ),
    )


def register(subparsers: Any) -> None:
    """Add the ``serve`` subcommand to the ``thermolab`` parser.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The subparsers of the top-level parser.
    """
    parser = subparsers.add_parser(
        "serve",
        help=_("run the remote laboratory (web server)"),
        description=_(
            "Run the remote laboratory: rigs shared by many watchers, one controller "
            "at a time, on http://HOST:PORT."
        ),
        epilog=_examples(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--host", default="127.0.0.1", help=_("address to listen on (127.0.0.1)"))
    parser.add_argument("--port", type=int, default=8000, help=_("port to listen on (8000)"))
    add_database_options(parser)
    parser.add_argument(
        "--speedup",
        type=float,
        metavar="X",
        help=_(
            "save X as the twin speed-up of every twin the lab runs, over the teachers' "
            "setting (demos and tests); without it each twin keeps its saved one"
        ),
    )
    parser.add_argument(
        "--request-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help=_("seconds a client has to send a whole request; slower ones are cut (10)"),
    )
    parser.add_argument(
        "--ssl-certfile", metavar="FILE.pem", help=_("serve HTTPS/WSS with this certificate")
    )
    parser.add_argument(
        "--ssl-keyfile", metavar="FILE.pem", help=_("the certificate's private key")
    )
    parser.add_argument(
        "--ca",
        metavar="FILE.pem",
        help=_(
            "CA certificate(s) to trust, besides the system's, for the owner worker's "
            "https:// address (a follower forwards rig requests there; the rig hosts' --ca)"
        ),
    )
    parser.add_argument(
        "--agent-grace",
        type=float,
        metavar="S",
        help=_(
            "seconds a rig host may be away: its run goes on and the controller keeps the "
            "turn for that long after a lost link; then the host ENDs the run and the rig is "
            "out of service (default 30: longer than a takeover)"
        ),
    )
    parser.add_argument(
        "--smtp",
        metavar="HOST:PORT",
        help=_("mail server for the rig-health alerts (none: no mail)"),
    )
    parser.add_argument(
        "--alert-to",
        action="append",
        default=[],
        metavar="ADDRESS",
        help=_("who gets the rig-health alerts (repeat for several)"),
    )
    parser.add_argument(
        "--broker",
        metavar="URL",
        help=_("join the other workers of this database over this broker (redis://HOST:PORT/DB)"),
    )
    parser.add_argument(
        "--advertise",
        metavar="URL",
        help=_("this worker's address for the other workers (http://HOST:PORT of --host/--port)"),
    )
    parser.add_argument(
        "--standby",
        action="store_true",
        help=_(
            "as a follower, take the rigs over when their owner's lease lapses (only on a "
            "machine that can open the lab's devices; docs/fleet.md)"
        ),
    )
    parser.add_argument(
        "--max-connections",
        type=int,
        default=CONNECTION_LIMIT,
        metavar="N",
        help=_("open connections beyond which new requests get 503 ({limit})").format(
            limit=CONNECTION_LIMIT
        ),
    )
    parser.add_argument(
        "--log-format",
        choices=("text", "json"),
        default="text",
        help=_("the server's log on standard error: text, or one JSON object a line (text)"),
    )
    from thermolab.cli.retention import add_retention_options

    add_retention_options(parser)
    parser.set_defaults(handler=_serve)


def lab_config_from_args(args: argparse.Namespace) -> LabConfig:
    """Build the :class:`~thermolab.lab.config.LabConfig` the options describe.

    Raises
    ------
    ConfigError
        For a bad configuration file or option value.
    """
    from thermolab.lab.config import default_config, load_config, resolve_data_dir
    from thermolab.lab.db import normalize_database_url

    data_dir = resolve_data_dir(args.data_dir)
    config = load_config(args.config, data_dir) if args.config else default_config(data_dir)
    config = config.with_overrides(
        database_url=args.database_url, speedup=getattr(args, "speedup", None)
    )
    normalize_database_url(config.database)
    # The retention period: the file's, then the environment's, then the options'.
    retention = config.retention.with_environment().over(
        getattr(args, "retention_months", None), getattr(args, "retention_action", None)
    )
    return replace(config, retention=retention)


def _check_port_free(host: str, port: int) -> None:
    from thermolab.cli import CliError

    if not 0 < port < 65536:
        raise CliError(_("--port {port} is not a TCP port (1-65535)").format(port=port), status=2)
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise CliError(
            _("cannot listen on {host}: {reason}").format(host=repr(host), reason=exc.strerror)
        ) from None
    family, kind, proto, _name, address = infos[0]
    with socket.socket(family, kind, proto) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(address)
        except OSError as exc:
            raise CliError(
                _(
                    "cannot listen on {host}:{port} ({reason}); is another server running? "
                    "choose another --port"
                ).format(host=host, port=port, reason=exc.strerror)
            ) from None


def make_private(config: LabConfig) -> list[str]:
    """Make the lab's files the server user's only; return what had to be tightened.

    Sets the process's umask to 077 (so every file the lab creates from now on
    is 0600, every folder 0700), creates the data folder 0700, and tightens
    the data folder and an existing SQLite database (with its ``-wal`` and
    ``-shm`` files) found with looser modes.
    """
    from sqlalchemy.engine import make_url

    os.umask(0o077)
    data_dir = config.data_dir
    data_dir.mkdir(mode=0o700, parents=True, exist_ok=True)
    paths = [data_dir]
    url = make_url(config.database)
    if url.get_backend_name() == "sqlite" and url.database not in (None, "", ":memory:"):
        database = Path(str(url.database))
        paths += [database, *(Path(f"{database}{end}") for end in ("-wal", "-shm", "-journal"))]
    tightened = []
    for path in paths:
        try:
            mode = stat.S_IMODE(path.stat().st_mode)
        except FileNotFoundError:
            continue
        if mode & 0o077:
            path.chmod(mode & 0o700)
            tightened.append(_("{path} (was {mode})").format(path=path, mode=f"{mode:o}"))
    return tightened


def _serve(args: argparse.Namespace) -> int:
    from thermolab.cli import CliError
    from thermolab.cli.first_start import first_start_message
    from thermolab.cli.retention import retention_line
    from thermolab.lab.fleet.workers import start_worker
    from thermolab.lab.http.app import create_app
    from thermolab.lab.rigs.opener import device_opener
    from thermolab.web import STATIC_DIR

    config = lab_config_from_args(args)
    if not 0 < args.request_timeout <= 3600:
        raise CliError(
            _("--request-timeout {value}: use 0 < S <= 3600").format(
                value=f"{args.request_timeout:g}"
            ),
            status=2,
        )
    if not 1 <= args.max_connections <= 100_000:
        raise CliError(
            _("--max-connections {value}: use 1 <= N <= 100000").format(value=args.max_connections),
            status=2,
        )
    _check_port_free(args.host, args.port)
    for path in make_private(config):
        print(
            _("warning: tightened permissions of {path} to the server's user only").format(
                path=path
            ),
            file=sys.stderr,
        )
    if args.agent_grace is None:
        from thermolab.lab.agents.hub import DEFAULT_GRACE

        args.agent_grace = DEFAULT_GRACE
    if not 0 < args.agent_grace <= 3600:
        raise CliError(
            _("--agent-grace {value}: use 0 < S <= 3600").format(value=f"{args.agent_grace:g}"),
            status=2,
        )
    if args.standby and args.broker is None:
        raise CliError(_("--standby: a standby follows an owner; give --broker too"), status=2)
    if args.ca is not None:
        _check_ca(args.ca)
    url = args.advertise or f"http://{args.host}:{args.port}"
    _announce_upgrade(config)
    lab, fleet, report = start_worker(
        config,
        opener=device_opener(),
        broker=args.broker,
        url=url,
        standby=args.standby,
    )
    lab.agents.grace = args.agent_grace
    lab.agents.notify = _mailer(args, config.title)
    collector: CollectorPolicy | None = None
    try:
        rigs = ", ".join(f"{rig.id} ({rig.spec})" for rig in config.rigs)
        scheme = "https" if args.ssl_certfile else "http"
        print(
            _("ThermoLab on {url}").format(url=f"{scheme}://{args.host}:{args.port}/"),
            file=sys.stderr,
        )
        print("  " + _("database: {url}").format(url=lab.db.display_url), file=sys.stderr)
        print("  " + _("rigs: {rigs}").format(rigs=rigs), file=sys.stderr)
        if fleet is not None:
            roles = {"alone": _("alone"), "owner": _("owner"), "follower": _("follower")}
            if getattr(lab, "standby", False):
                standing = _("broker: {url} ({role} on standby)")
            else:
                standing = _("broker: {url} ({role})")
            role = roles.get(fleet.role, fleet.role)
            print("  " + standing.format(url=args.broker, role=role), file=sys.stderr)
        twins = [lab.config.rig(rig.id) for rig in config.rigs if rig.lab_twin]
        paces = ", ".join(f"{rig.id} {rig.twin_speedup:g}x" for rig in twins)
        if twins and (
            config.speedup_override is not None or any(r.twin_speedup != 1 for r in twins)
        ):
            given = config.speedup_override is not None
            if given:
                words = _("twin speed-ups (--speedup): {paces}").format(paces=paces)
            else:
                words = _("twin speed-ups: {paces}").format(paces=paces)
            print(f"  {words}", file=sys.stderr)
        if config.retention.months is not None:
            print(
                "  " + _("retention: {policy}").format(policy=retention_line(config)),
                file=sys.stderr,
            )
        for rig_id, fault in report.faults.items():
            print(
                "  " + _("warning: rig {rig}: {fault}").format(rig=rig_id, fault=fault),
                file=sys.stderr,
            )
        if report.teachers == 0:
            print(first_start_message(args, config), file=sys.stderr)
        static = STATIC_DIR if (STATIC_DIR / "index.html").is_file() else None
        app = create_app(config, static, lab=lab, close_lab=True, fleet=fleet, owner_ca=args.ca)
        # What exists now (the imported libraries, the lab, the app) lives as long as the
        # server: keep it out of the collector's full passes, which otherwise stop every
        # thread, the live stream's included, for 0.1-0.2 s each (benchmarks/bench_live.py),
        # and what survives a pass later out of the next (lab/operations/collector.py).
        from thermolab.lab.operations.collector import CollectorPolicy

        collector = CollectorPolicy(lambda: all(lab.running(rig.id) is None for rig in config.rigs))
        collector.start()
        if os.environ.get(WARM_UP_VARIABLE, "1") != "0":
            threading.Thread(target=_warm_up_methods, name="warm-up", daemon=True).start()
        run_server(
            app,
            args.host,
            args.port,
            request_timeout=args.request_timeout,
            tls=(args.ssl_certfile, args.ssl_keyfile),
            max_connections=args.max_connections,
            log_format=args.log_format,
        )
    finally:
        if collector is not None:
            collector.stop()
        lab.close()
    return 0


WARM_UP_VARIABLE = "THERMOLAB_WARM_UP"
"""``0`` in the environment: no warm-up of the methods' kernels at start (the test
suite's many short-lived servers, most of which never start a run)."""


def _warm_up_methods() -> None:
    """Load the identification kernels while nobody waits (runner/methods.py)."""
    import logging
    import time

    from thermolab.runner.methods import warm_up_every_method

    started = time.perf_counter()
    methods = warm_up_every_method()
    logging.getLogger("thermolab.serve").info(
        "identification methods ready (%s) in %.1f s",
        ", ".join(methods),
        time.perf_counter() - started,
    )


def _check_ca(cafile: str) -> None:
    """Refuse, in one line, a ``--ca`` that cannot be read or holds no certificate."""
    import ssl

    from thermolab.cli import CliError
    from thermolab.lab.http.forward import owner_tls

    try:
        owner_tls(cafile)
    except (OSError, ssl.SSLError) as exc:
        raise CliError(
            _("--ca {path}: not a CA certificate file ({reason})").format(path=cafile, reason=exc),
            status=2,
        ) from None


def _announce_upgrade(config: LabConfig) -> None:
    """Say which migrations the start will run on an existing database, before it does."""
    from thermolab.lab.db import Database
    from thermolab.lab.operations.backup import known_revisions

    db = Database(config.database, pool_size=1, max_overflow=0)
    try:
        tables = db.table_names()
        current = db.current_revision() if tables else None
    except Exception:  # unreachable: the start says so, with the reason
        return
    finally:
        db.close()
    revisions = known_revisions()
    if current is None or current not in revisions or current == revisions[-1]:
        return
    pending = revisions[revisions.index(current) + 1 :]
    print(
        "  "
        + _(
            "database: upgrading its schema from revision {current} to {latest} "
            "({count} migrations, in one transaction; other commands wait for it)"
        ).format(current=current, latest=revisions[-1], count=len(pending)),
        file=sys.stderr,
    )


def _mailer(args: argparse.Namespace, title: str) -> Any:
    from thermolab.cli import CliError
    from thermolab.lab.agents.notify import Mailer

    if args.smtp is None:
        return None
    host, _colon, port = args.smtp.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536 or not args.alert_to:
        raise CliError(
            _("--smtp {value}: use HOST:PORT with --alert-to ADDRESS").format(
                value=repr(args.smtp)
            ),
            status=2,
        )
    return Mailer(host, int(port), tuple(args.alert_to), lab_title=title)
