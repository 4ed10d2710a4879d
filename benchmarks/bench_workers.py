"""Watchers spread over 1, 2, 4 web workers on one PostgreSQL and one Redis bus.

For each number of workers W and each number of watchers N: a fresh
PostgreSQL schema, W ``thermolab serve --broker redis://...`` processes (the
first owns the rig, the others follow, :mod:`thermolab.lab.fleet.workers`), one
teacher running the realistic twin at 10 samples/s (LSM and WLSM, a sample
and an estimate message each), and N watchers split evenly over the workers
(the client processes and the per-watcher delay figures of
``bench_live.py``). Beside them, in the same run, the broker's own fan-out
alone (``bench_bus.py``'s Redis pub/sub: the rig's 20 messages a second to W
subscriber processes).

Usage::

    .venv/bin/python benchmarks/bench_workers.py                           # 1,2,4 x 1000,2000
    .venv/bin/python benchmarks/bench_workers.py --workers 1,2 --watchers 2000 --seconds 15
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import subprocess
import sys
import tempfile
import textwrap
import uuid
from pathlib import Path
from typing import Any

import httpx

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_bus
import bench_live

PYTHON = sys.executable
POSTGRES = os.environ.get(
    "THERMOLAB_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test"
)
REDIS = os.environ.get("THERMOLAB_TEST_REDIS_URL", "redis://127.0.0.1:6379/0")


def new_schema() -> tuple[str, str]:
    """A fresh schema on the test server: (its name, a URL whose search_path is it)."""
    import psycopg

    schema = f"bench_workers_{uuid.uuid4().hex[:10]}"
    dsn = POSTGRES.replace("postgresql+psycopg://", "postgresql://")
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute(f'CREATE SCHEMA "{schema}"')
    return schema, f"{POSTGRES}?options=-csearch_path%3D{schema}"


def drop_schema(schema: str) -> None:
    import psycopg

    dsn = POSTGRES.replace("postgresql+psycopg://", "postgresql://")
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA "{schema}" CASCADE')


async def start_watchers(
    urls: list[str], cookie: str, watchers: int
) -> list[asyncio.subprocess.Process]:
    """One client process per worker, its share of the watchers; the first holds the stalled one."""
    shares = [
        watchers // len(urls) + (1 if i < watchers % len(urls) else 0) for i in range(len(urls))
    ]
    clients = []
    for i, (url, share) in enumerate(zip(urls, shares, strict=True)):
        command = [bench_live.SCRIPT, "--role", "clients", "--url", url, "--count", str(share)]
        command += ["--cookie", cookie, "--ping", "5"] + (["--stall"] if i == 0 else [])
        clients.append(
            await asyncio.create_subprocess_exec(
                PYTHON, *command, stdout=asyncio.subprocess.PIPE, limit=2**28
            )
        )
    for client in clients:
        await bench_live.expect(client, "ready", 180)
    return clients


async def bench(
    workers: int, watchers: int, seconds: float, server_log: Path | None = None
) -> dict[str, Any]:
    samples = round(seconds / bench_live.DT)
    schema, url = new_schema()
    servers: list[subprocess.Popen[bytes]] = []
    clients: list[asyncio.subprocess.Process] = []
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp, "lab.toml")
        config.write_text(textwrap.dedent(bench_live.LAB_TOML))
        env = dict(os.environ, THERMOLAB_DATA_DIR=tmp)
        common = ["--config", str(config), "--database-url", url]
        subprocess.run(
            [PYTHON, "-m", "thermolab", "user", "add", "tina", "--role", "teacher",
             "--password-stdin", *common],
            input="bench-password\n", text=True, env=env, check=True, capture_output=True,
        )  # fmt: skip
        try:
            bases = []
            for _ in range(workers):  # one after the other: the first owns the rig
                port = bench_live.free_port()
                serve = [PYTHON, "-m", "thermolab", "serve", "--port", str(port), *common]
                serve += ["--broker", REDIS, "--max-connections", "20000"]
                log = subprocess.DEVNULL
                if server_log is not None:  # each worker's own file: what went wrong, if anything
                    log = open(f"{server_log}-{watchers}-{workers}-{len(servers)}.log", "wb")  # noqa: SIM115
                servers.append(subprocess.Popen(serve, env=env, stdout=log, stderr=log))
                bases.append(f"http://127.0.0.1:{port}")
                bench_live.wait_for(bases[-1] + "/openapi.json", 90)
            async with httpx.AsyncClient(base_url=bases[0], timeout=60) as http:
                login = await http.post(
                    "/api/session", json={"username": "tina", "password": "bench-password"}
                )
                login.raise_for_status()
                cookie = f"thermolab_session={login.cookies['thermolab_session']}"
                headers = {"Cookie": cookie}
                (await http.post("/api/rigs/twin/control", headers=headers)).raise_for_status()

                async def keep_control() -> None:
                    while True:
                        await asyncio.sleep(5.0)
                        await http.post("/api/rigs/twin/heartbeat", headers=headers)

                heartbeat = asyncio.create_task(keep_control())
                live = [b.replace("http", "ws", 1) + "/api/rigs/twin/live" for b in bases]
                clients = await start_watchers(live, cookie, watchers)
                cpu = bench_live.CpuWindow(
                    {"server": [s.pid for s in servers], "clients": [c.pid for c in clients]}
                )
                started = await http.post(
                    "/api/rigs/twin/runs",
                    headers=headers,
                    json={"dt": bench_live.DT, "samples": samples,
                          "signal": "square:4:6:0.1", "methods": ["lsm", "wlsm"]},
                )  # fmt: skip
                started.raise_for_status()
                try:
                    results, figures = await bench_live.measure(clients, cpu, seconds)
                finally:
                    heartbeat.cancel()
                    with contextlib.suppress(asyncio.CancelledError):
                        await heartbeat
        finally:
            for client in clients:
                with contextlib.suppress(ProcessLookupError):
                    client.kill()
            for server in servers:
                server.terminate()
            for server in servers:
                try:
                    server.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    server.kill()
            drop_schema(schema)
    row = bench_live.summarise(f"{workers} worker(s)", results, figures, samples)
    row["expected_s"] = seconds
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", default="1,2,4", help="comma-separated (1,2,4)")
    parser.add_argument("--watchers", default="1000,2000", help="comma-separated (1000,2000)")
    parser.add_argument("--seconds", type=float, default=15.0, help="length of each run (15)")
    parser.add_argument(
        "--server-log",
        type=Path,
        metavar="PREFIX",
        help="keep each worker's output in PREFIX-<watchers>-<workers>-<i>.log",
    )
    args = parser.parse_args()
    print(
        f"one rig at {1 / bench_live.DT:g} samples/s, {args.seconds:g} s per run, watchers "
        f"split over the workers (pinging every 5 s); {os.cpu_count()} cores, "
        f"load {os.getloadavg()[0]:.1f}"
    )
    print(
        "  delays in ms beyond the fastest delivery seen; CPU in % of one core "
        "(servers together; machine: % of all cores)"
    )
    print(
        "     server      p50      p99      max  deliv%  frm/s  srvCPU cliCPU  mach%   "
        "stalled watcher"
    )
    for watchers in [int(n) for n in args.watchers.split(",")]:
        print(f"  -- {watchers} watchers")
        for workers in [int(n) for n in args.workers.split(",")]:
            row = asyncio.run(bench(workers, watchers, args.seconds, args.server_log))
            bench_live.print_row(row)
            alone = bench_bus.run_bus("redis", 20.0, min(args.seconds, 5.0), workers)
            if "p99" in alone:
                print(
                    f"      the broker alone (20 msg/s to {workers} subscribers): "
                    f"p50 {alone['p50']:.2f} ms, p99 {alone['p99']:.2f} ms, "
                    f"broker CPU {alone['broker_cpu']:.1f} %"
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
