"""``thermolab serve``: run the remote laboratory.

With no options it serves one digital twin at http://127.0.0.1:8000 with a
SQLite database in the data folder (``--data-dir``, ``$THERMOLAB_DATA_DIR``
or a per-user folder): nothing else to install. ``--config FILE.toml`` declares
more rigs and the access policy (see :mod:`thermolab.lab.config`);
``--database-url`` uses PostgreSQL instead.

Server limits (issue #13): uvicorn runs the pure-Python h11 parser, whose
incomplete-event bound refuses request heads over 16 KiB (httptools, which
uvicorn picks by default, has none), a client has ``--request-timeout``
seconds to send a whole request (a slow or silent client is cut), a WebSocket
frame over 1 MiB is refused from its header (``WS_MAX_SIZE``), an idle
keep-alive connection is closed after 5 s, and beyond 1000 open connections
(``--max-connections``) new requests get 503. Files: the process's umask is 077, so the data folder,
the SQLite database (and its journal) and the run records are the server
user's only (0700/0600); looser modes found at start are tightened, with a
warning.
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import os
import shutil
import socket
import stat
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from thermolab.lab.config import LabConfig

__all__ = [
    "CONNECTION_LIMIT",
    "HEAD_LIMIT",
    "KEEP_ALIVE_TIMEOUT",
    "WS_MAX_SIZE",
    "add_database_options",
    "lab_config_from_args",
    "make_private",
    "register",
]

HEAD_LIMIT = 16 * 1024
"""Largest request head (request line and headers) in bytes; larger ones are refused."""
KEEP_ALIVE_TIMEOUT = 5
"""Seconds an idle keep-alive connection stays open."""
CONNECTION_LIMIT = 1000
"""Open connections (HTTP and WebSocket) beyond which new requests get 503."""
WS_MAX_SIZE = 2**20
"""Largest WebSocket message read: a bigger frame is refused from its header (close 1009).

A live client's messages are refused over 4 KiB by the lab itself; rig hosts'
messages, on the same server, stay under the 1 MiB their own end accepts.
"""

_EXAMPLES = """\
examples:
  thermolab serve
  thermolab --data-dir /srv/thermolab serve --host 0.0.0.0 --config lab.toml
  thermolab serve --database-url postgresql+psycopg://lab@localhost/thermolab
  thermolab serve --speedup 50        # saves 50 as every twin's speed-up (demos)
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
        help="save X as the twin speed-up of every twin the lab runs, over the teachers' "
        "setting (demos and tests); without it each twin keeps its saved one",
    )
    parser.add_argument(
        "--request-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="seconds a client has to send a whole request; slower ones are cut (10)",
    )
    parser.add_argument(
        "--ssl-certfile", metavar="FILE.pem", help="serve HTTPS/WSS with this certificate"
    )
    parser.add_argument("--ssl-keyfile", metavar="FILE.pem", help="the certificate's private key")
    parser.add_argument(
        "--agent-grace",
        type=float,
        default=10.0,
        metavar="S",
        help="seconds a remote rig's run outlives a lost link before its host ENDs it (10)",
    )
    parser.add_argument(
        "--smtp", metavar="HOST:PORT", help="mail server for the rig-health alerts (none: no mail)"
    )
    parser.add_argument(
        "--alert-to",
        action="append",
        default=[],
        metavar="ADDRESS",
        help="who gets the rig-health alerts (repeat for several)",
    )
    parser.add_argument(
        "--broker",
        metavar="URL",
        help="join the other workers of this database over this broker (redis://HOST:PORT/DB)",
    )
    parser.add_argument(
        "--advertise",
        metavar="URL",
        help="this worker's address for the other workers (http://HOST:PORT of --host/--port)",
    )
    parser.add_argument(
        "--standby",
        action="store_true",
        help="as a follower, take the rigs over when their owner's lease lapses (only on a "
        "machine that can open the lab's devices; docs/fleet.md)",
    )
    parser.add_argument(
        "--max-connections",
        type=int,
        default=CONNECTION_LIMIT,
        metavar="N",
        help=f"open connections beyond which new requests get 503 ({CONNECTION_LIMIT})",
    )
    parser.add_argument(
        "--log-format",
        choices=("text", "json"),
        default="text",
        help="the server's log on standard error: text, or one JSON object a line (text)",
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


def command_name() -> str:
    """``thermolab`` as the user can type it here: the quick start's ``.venv/bin/thermolab``
    is not on PATH (its venv is not activated), so a hint naming plain ``thermolab``
    would fail as printed."""
    script = Path(sys.argv[0])
    if script.name != "thermolab":  # python -m thermolab, or an embedding program
        return "thermolab"
    found = shutil.which("thermolab")
    if found and Path(found).resolve() == script.resolve():
        return "thermolab"
    try:
        return str(Path(".") / script.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(script.resolve())


def _teacher_hint(args: argparse.Namespace) -> str:
    parts = [command_name()]
    if args.data_dir:
        parts += ["--data-dir", args.data_dir]
    parts += ["user", "add", "NAME", "--role", "admin"]
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
            tightened.append(f"{path} (was {mode:o})")
    return tightened


def _serve(args: argparse.Namespace) -> int:
    from thermolab.cli import CliError
    from thermolab.lab.fleet.workers import start_worker
    from thermolab.lab.http.app import create_app
    from thermolab.lab.rigs.devices import device_opener
    from thermolab.web import STATIC_DIR

    config = lab_config_from_args(args)
    if not 0 < args.request_timeout <= 3600:
        raise CliError(f"--request-timeout {args.request_timeout:g}: use 0 < S <= 3600", status=2)
    if not 1 <= args.max_connections <= 100_000:
        raise CliError(f"--max-connections {args.max_connections}: use 1 <= N <= 100000", status=2)
    _check_port_free(args.host, args.port)
    for path in make_private(config):
        print(
            f"warning: tightened permissions of {path} to the server's user only", file=sys.stderr
        )
    if not 0 < args.agent_grace <= 3600:
        raise CliError(f"--agent-grace {args.agent_grace:g}: use 0 < S <= 3600", status=2)
    if args.standby and args.broker is None:
        raise CliError("--standby: a standby follows an owner; give --broker too", status=2)
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
    try:
        rigs = ", ".join(f"{rig.id} ({rig.spec})" for rig in config.rigs)
        scheme = "https" if args.ssl_certfile else "http"
        print(f"ThermoLab on {scheme}://{args.host}:{args.port}/", file=sys.stderr)
        print(f"  database: {lab.db.display_url}", file=sys.stderr)
        print(f"  rigs: {rigs}", file=sys.stderr)
        if fleet is not None:
            standing = " on standby" if getattr(lab, "standby", False) else ""
            print(f"  broker: {args.broker} ({fleet.role}{standing})", file=sys.stderr)
        twins = [lab.config.rig(rig.id) for rig in config.rigs if rig.lab_twin]
        paces = ", ".join(f"{rig.id} {rig.twin_speedup:g}x" for rig in twins)
        if twins and (
            config.speedup_override is not None or any(r.twin_speedup != 1 for r in twins)
        ):
            given = " (--speedup)" if config.speedup_override is not None else ""
            print(f"  twin speed-ups{given}: {paces}", file=sys.stderr)
        for rig_id, fault in report.faults.items():
            print(f"  warning: rig {rig_id}: {fault}", file=sys.stderr)
        if report.teachers == 0:
            print(
                "  No teacher account yet. Create the lab's administrator (a teacher who also\n"
                "  manages accounts and rigs; then log in at the address above) with:\n"
                f"    {_teacher_hint(args)}\n"
                "  then teachers with --role teacher and students with --role student (or,\n"
                "  once logged in, upload a class list on a course's page).",
                file=sys.stderr,
            )
        static = STATIC_DIR if (STATIC_DIR / "index.html").is_file() else None
        app = create_app(config, static, lab=lab, close_lab=True, fleet=fleet)
        # What exists now (the imported libraries, the lab, the app) lives as long as the
        # server: keep it out of the collector's full passes, which otherwise stop every
        # thread, the live stream's included, for 0.1-0.2 s each (benchmarks/bench_live.py).
        gc.collect()
        gc.freeze()
        _run_server(
            app,
            args.host,
            args.port,
            request_timeout=args.request_timeout,
            tls=(args.ssl_certfile, args.ssl_keyfile),
            max_connections=args.max_connections,
            log_format=args.log_format,
        )
    finally:
        lab.close()
    return 0


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
        f"  database: upgrading its schema from revision {current} to {revisions[-1]} "
        f"({len(pending)} migrations, in one transaction; other commands wait for it)",
        file=sys.stderr,
    )


def _mailer(args: argparse.Namespace, title: str) -> Any:
    from thermolab.cli import CliError
    from thermolab.lab.agents.notify import Mailer

    if args.smtp is None:
        return None
    host, _, port = args.smtp.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536 or not args.alert_to:
        raise CliError(f"--smtp {args.smtp!r}: use HOST:PORT with --alert-to ADDRESS", status=2)
    return Mailer(host, int(port), tuple(args.alert_to), lab_title=title)


def _bounded_h11(request_timeout: float) -> type[asyncio.Protocol]:
    """uvicorn's h11 protocol, cutting a client that takes too long to send a request.

    uvicorn bounds the wait between requests (keep-alive) but not the wait for
    a request: a client that sends a head byte by byte (slowloris), a body
    slowly, or nothing at all would hold its connection forever. The timer
    runs from the connection (or the first byte of the next request) until the
    whole request is in.
    """
    import h11
    from uvicorn.protocols.http.h11_impl import H11Protocol

    class BoundedH11Protocol(H11Protocol):
        _request_timer: asyncio.TimerHandle | None = None
        _upgraded = False

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self._arm()

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if self._upgraded:
                # The WebSocket protocol owns the connection now; h11 still reads the
                # upgrade request as SEND_BODY, and a timer armed here cut every live
                # socket after request_timeout seconds.
                return
            if self.conn.their_state in (h11.IDLE, h11.SEND_BODY):
                self._arm(only_if_unarmed=True)  # a request has begun: it must end in time
            else:
                self._disarm()

        def connection_lost(self, exc: Exception | None) -> None:
            self._disarm()
            super().connection_lost(exc)

        def handle_websocket_upgrade(self, event: h11.Request) -> None:
            self._upgraded = True
            self._disarm()
            super().handle_websocket_upgrade(event)

        def _arm(self, *, only_if_unarmed: bool = False) -> None:
            if only_if_unarmed and self._request_timer is not None:
                return
            self._disarm()
            self._request_timer = self.loop.call_later(request_timeout, self._too_slow)

        def _disarm(self) -> None:
            if self._request_timer is not None:
                self._request_timer.cancel()
                self._request_timer = None

        def _too_slow(self) -> None:
            self._request_timer = None
            if (
                self.conn.their_state in (h11.IDLE, h11.SEND_BODY)
                and not self.transport.is_closing()
            ):
                self.logger.info("closed a connection that was too slow to send its request")
                self.transport.close()

    return BoundedH11Protocol


def _framed_websockets() -> type[asyncio.Protocol]:
    """uvicorn's WebSocket protocol, offering the live stream direct writes to its socket.

    The ASGI scope gets :data:`~thermolab.lab.live.fanout.FRAMES_EXTENSION`: a
    writer that puts a whole, ready-made frame on the connection's transport
    (the frame the channel built once for every client). The protocol's own
    frames (pings, close) go to the same transport from the same thread, so
    frames never interleave; nothing is written once a close is sent.
    """
    from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol
    from websockets.http11 import Request

    from thermolab.lab.live.fanout import FRAMES_EXTENSION

    class Frames:
        __slots__ = ("protocol",)

        def __init__(self, protocol: WebSocketsSansIOProtocol) -> None:
            self.protocol = protocol

        def write(self, frame: bytes) -> bool:
            protocol = self.protocol
            transport = protocol.transport
            if protocol.close_sent or transport.is_closing():
                return False
            transport.write(frame)
            return True

        def buffered(self) -> int:
            size: int = self.protocol.transport.get_write_buffer_size()
            return size

    class FramedWebSockets(WebSocketsSansIOProtocol):
        def handle_connect(self, event: Request) -> None:
            super().handle_connect(event)
            scope = getattr(self, "scope", None)  # none when the handshake was refused
            if scope is not None:
                scope["extensions"][FRAMES_EXTENSION] = Frames(self)

    return FramedWebSockets


def _run_server(
    app: Any,
    host: str,
    port: int,
    *,
    request_timeout: float = 10.0,
    tls: tuple[str | None, str | None] = (None, None),
    max_connections: int = CONNECTION_LIMIT,
    log_format: str = "text",
) -> None:
    import uvicorn

    from thermolab.lab.operations.logs import log_config

    logging_config = log_config("json" if log_format == "json" else "text")
    # uvicorn's default (its coloured text) unless JSON lines were asked for.
    logging: Any = uvicorn.config.LOGGING_CONFIG if logging_config is None else logging_config

    # Live messages are small and go to many clients: compressing each one for each
    # client (permessage-deflate keeps a context per connection) cost the server more
    # than everything else in sending them (benchmarks/bench_live.py).
    uvicorn.run(
        app,
        host=host,
        port=port,
        log_level="info",
        log_config=logging,
        # X-Forwarded-For is believed only from access.trusted_proxies, in the app itself
        # (uvicorn's default would trust any proxy on 127.0.0.1).
        proxy_headers=False,
        ws_per_message_deflate=False,
        ws_max_size=WS_MAX_SIZE,
        http=_bounded_h11(request_timeout),
        ws=_framed_websockets(),
        h11_max_incomplete_event_size=HEAD_LIMIT,
        timeout_keep_alive=KEEP_ALIVE_TIMEOUT,
        limit_concurrency=max_connections,
        # TLS (wss:// for rig hosts): uvicorn's own, with the certificate given.
        ssl_certfile=tls[0],
        ssl_keyfile=tls[1],
    )
