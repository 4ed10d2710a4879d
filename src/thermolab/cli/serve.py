"""``thermolab serve``: run the remote laboratory.

With no options it serves one digital twin at http://127.0.0.1:8000 with a
SQLite database in the data folder (``--data-dir``, ``$THERMOLAB_DATA_DIR``
or a per-user folder): nothing else to install. ``--config FILE.toml`` declares
more rigs and the access policy (see :mod:`thermolab.lab.config`);
``--database-url`` uses PostgreSQL instead.
"""

from __future__ import annotations

import argparse
import gc
import socket
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from thermolab.lab.config import LabConfig

__all__ = ["add_database_options", "lab_config_from_args", "register"]

_EXAMPLES = """\
examples:
  thermolab serve
  thermolab --data-dir /srv/thermolab serve --host 0.0.0.0 --config lab.toml
  thermolab serve --database-url postgresql+psycopg://lab@localhost/thermolab
  thermolab serve --speedup 50        # twins run 50x faster than real time (demos)
"""


def add_database_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--config`` and ``--database-url`` (shared by ``serve`` and ``user``)."""
    parser.add_argument(
        "--config",
        metavar="FILE.toml",
        help="lab configuration: rigs, limits, access policy, database (default: one twin)",
    )
    parser.add_argument(
        "--database-url",
        metavar="URL",
        help="database to use instead of SQLite in the data folder "
        "(e.g. postgresql+psycopg://USER@HOST/DB)",
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
        help="run the remote laboratory (web server)",
        description="Run the remote laboratory: rigs shared by many watchers, one controller "
        "at a time, on http://HOST:PORT.",
        epilog=_EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (127.0.0.1)")
    parser.add_argument("--port", type=int, default=8000, help="port to listen on (8000)")
    add_database_options(parser)
    parser.add_argument(
        "--speedup",
        type=float,
        metavar="X",
        help="run simulated rigs X times faster than real time (demos and tests)",
    )
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
    return config


def _teacher_hint(args: argparse.Namespace) -> str:
    parts = ["thermolab"]
    if args.data_dir:
        parts += ["--data-dir", args.data_dir]
    parts += ["user", "add", "NAME", "--role", "teacher"]
    if args.config:
        parts += ["--config", args.config]
    if args.database_url:
        parts += ["--database-url", args.database_url]
    return " ".join(parts)


def _check_port_free(host: str, port: int) -> None:
    from thermolab.cli import CliError

    if not 0 < port < 65536:
        raise CliError(f"--port {port} is not a TCP port (1-65535)", status=2)
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise CliError(f"cannot listen on {host!r}: {exc.strerror}") from None
    family, kind, proto, _, address = infos[0]
    with socket.socket(family, kind, proto) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(address)
        except OSError as exc:
            raise CliError(
                f"cannot listen on {host}:{port} ({exc.strerror}); is another server running? "
                "choose another --port"
            ) from None


def _serve(args: argparse.Namespace) -> int:
    from thermolab.lab.devices import device_opener
    from thermolab.lab.http.app import create_app
    from thermolab.lab.service import Lab
    from thermolab.web import STATIC_DIR

    config = lab_config_from_args(args)
    _check_port_free(args.host, args.port)
    lab = Lab(config, opener=device_opener(config.speedup), exclusive=True)
    try:
        report = lab.start()
        rigs = ", ".join(f"{rig.id} ({rig.spec})" for rig in config.rigs)
        print(f"ThermoLab on http://{args.host}:{args.port}/", file=sys.stderr)
        print(f"  database: {lab.db.display_url}", file=sys.stderr)
        print(f"  rigs: {rigs}", file=sys.stderr)
        if config.speedup != 1.0:
            print(
                f"  simulated rigs run {config.speedup:g}x faster than real time", file=sys.stderr
            )
        for rig_id, fault in report.faults.items():
            print(f"  warning: rig {rig_id}: {fault}", file=sys.stderr)
        if report.teachers == 0:
            print(
                "  No teacher account yet. Create one (then log in at the address above) with:\n"
                f"    {_teacher_hint(args)}",
                file=sys.stderr,
            )
        static = STATIC_DIR if (STATIC_DIR / "index.html").is_file() else None
        app = create_app(config, static, lab=lab, close_lab=True)
        # What exists now (the imported libraries, the lab, the app) lives as long as the
        # server: keep it out of the collector's full passes, which otherwise stop every
        # thread, the live stream's included, for 0.1-0.2 s each (benchmarks/bench_live.py).
        gc.collect()
        gc.freeze()
        _run_server(app, args.host, args.port)
    finally:
        lab.close()
    return 0


def _run_server(app: Any, host: str, port: int) -> None:
    import uvicorn

    # Live messages are small and go to many clients: compressing each one for each
    # client (permessage-deflate keeps a context per connection) cost the server more
    # than everything else in sending them (benchmarks/bench_live.py).
    uvicorn.run(
        app,
        host=host,
        port=port,
        log_level="info",
        proxy_headers=True,
        ws_per_message_deflate=False,
    )
