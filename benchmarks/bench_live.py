"""Load benchmark of the live stream: N watchers of one rig sampled at 10 Hz.

Starts ``thermolab serve`` in a child process (a SQLite database in a temporary
folder, the paper's twin in real time), takes control, starts a run at
``dt = 0.1 s`` with two identifiers, and connects N watchers over real
WebSockets on loopback (all in this process, on one asyncio loop), plus one
*stalled* watcher that connects and never reads. Each watcher notes when each
sample ``k`` of the run arrives.

Delay of a sample at a watcher = arrival time - (t0 + k dt), with t0 the run's
start as the earliest arrival of any sample shows it (min over watchers and k
of ``arrival - k dt``): the figures are the delay beyond the fastest delivery
seen, i.e. queueing in the server and clients, not the loopback's fixed cost.

Peer, measured in the same run the same way: a bare ``websockets`` broadcast
server (one process, the same JSON text sent to every client at 10 Hz, no
database, no identifiers) with the same N watchers.

Usage::

    .venv/bin/python benchmarks/bench_live.py                  # 500 watchers, 20 s
    .venv/bin/python benchmarks/bench_live.py --watchers 100 --seconds 10
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import httpx
import websockets

PYTHON = sys.executable
DT = 0.1


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def wait_for(url: str, seconds: float = 30.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        with contextlib.suppress(httpx.HTTPError):
            httpx.get(url, timeout=1.0)
            return
        time.sleep(0.1)
    raise SystemExit(f"the server at {url} did not start")


async def watch(
    url: str, headers: dict[str, str], arrivals: list[tuple[int, float]], done: asyncio.Event
) -> dict[str, int]:
    """Receive until the run ends (or ``done``); note (k, arrival) of each run sample."""
    counts: dict[str, int] = {}
    async with websockets.connect(url, additional_headers=headers, max_size=2**24) as ws:
        while not done.is_set():
            try:
                text = await asyncio.wait_for(ws.recv(), timeout=1.0)
            except TimeoutError:
                continue
            now = time.monotonic()
            if isinstance(text, str) and text.startswith('{"type":"estimate"'):
                counts["estimate"] = counts.get("estimate", 0) + 1
                continue  # the bulk of the rest: not parsed, to keep the clients' side light
            message = json.loads(text)
            kind = message.get("type")
            counts[kind] = counts.get(kind, 0) + 1
            if (kind == "sample" and message.get("run") is not None) or kind == "tick":
                arrivals.append((message["k"], now))
            elif (kind == "run" and message.get("event") == "ended") or kind == "end":
                break
    return counts


async def stall(url: str, headers: dict[str, str], done: asyncio.Event) -> str:
    """Connect and never read: the server must cut this client, not slow the others.

    With ``max_queue=1`` the client library stops reading the socket once one
    message waits, so the server's writes to it back up.
    """
    try:
        async with websockets.connect(url, additional_headers=headers, max_queue=1) as ws:
            await done.wait()
            return "still connected" if ws.close_code is None else f"closed {ws.close_code}"
    except websockets.ConnectionClosed as exc:
        return f"closed {exc.code}"


def delays(all_arrivals: list[list[tuple[int, float]]]) -> tuple[list[float], int]:
    flat = [(k, t) for arrivals in all_arrivals for k, t in arrivals]
    if not flat:
        return [], 0
    t0 = min(t - k * DT for k, t in flat)
    return sorted((t - (t0 + k * DT)) * 1000.0 for k, t in flat), len(flat)


def report(name: str, values: list[float], count: int, expected: int) -> dict[str, float]:
    if not values:
        print(f"{name:>10}: no samples received")
        return {}
    p = lambda q: values[min(len(values) - 1, int(q * len(values)))]  # noqa: E731
    figures = {
        "median": statistics.median(values),
        "p99": p(0.99),
        "max": values[-1],
        "received": count / expected if expected else 0.0,
    }
    print(
        f"{name:>10}: median {figures['median']:6.1f} ms   p99 {figures['p99']:6.1f} ms   "
        f"max {figures['max']:7.1f} ms   received {100 * figures['received']:5.1f} % "
        f"of {expected} sample deliveries"
    )
    return figures


async def bench_thermolab(watchers: int, seconds: float) -> dict[str, float]:
    port = free_port()
    samples = int(seconds / DT)
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp, "lab.toml")
        config.write_text(
            textwrap.dedent(
                """
                [access]
                login_attempts_per_address = 1000
                max_body_bytes = 65536

                [rig_defaults]
                control_time_limit = 3600
                idle_limit = 0

                [[rigs]]
                id = "twin"
                title = "Twin"
                spec = "sim:paper-practical"
                """
            )
        )
        env = dict(os.environ, THERMOLAB_DATA_DIR=tmp)
        subprocess.run(
            [
                PYTHON,
                "-m",
                "thermolab",
                "user",
                "add",
                "tina",
                "--role",
                "teacher",
                "--password-stdin",
                "--config",
                str(config),
            ],
            input="bench-password\n",
            text=True,
            env=env,
            check=True,
            capture_output=True,
        )
        server = subprocess.Popen(
            [PYTHON, "-m", "thermolab", "serve", "--port", str(port), "--config", str(config)],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            base = f"http://127.0.0.1:{port}"
            wait_for(base + "/openapi.json")
            async with httpx.AsyncClient(base_url=base) as http:
                login = await http.post(
                    "/api/session", json={"username": "tina", "password": "bench-password"}
                )
                login.raise_for_status()
                headers = {"Cookie": f"thermolab_session={login.cookies['thermolab_session']}"}
                (await http.post("/api/rigs/twin/control", headers=headers)).raise_for_status()
                url = f"ws://127.0.0.1:{port}/api/rigs/twin/live"
                done = asyncio.Event()
                arrivals: list[list[tuple[int, float]]] = [[] for _ in range(watchers)]
                clients = [
                    asyncio.create_task(watch(url, headers, arrivals[i], done))
                    for i in range(watchers)
                ]
                stalled = asyncio.create_task(stall(url, headers, done))
                await asyncio.sleep(2.0 + watchers / 200)  # let everyone connect
                started = await http.post(
                    "/api/rigs/twin/runs",
                    headers=headers,
                    json={
                        "dt": DT,
                        "samples": samples,
                        "signal": "square:4:6:0.1",
                        "methods": ["lsm", "wlsm"],
                    },
                )
                started.raise_for_status()

                async def keep_control() -> None:  # the controller's page polls the rig
                    while not done.is_set():
                        await http.post("/api/rigs/twin/heartbeat", headers=headers)
                        await asyncio.sleep(5.0)

                heartbeat = asyncio.create_task(keep_control())
                results = await asyncio.wait_for(asyncio.gather(*clients), seconds + 60)
                done.set()
                await heartbeat
                stalled_result = await stalled
        finally:
            server.terminate()
            with contextlib.suppress(subprocess.TimeoutExpired):
                server.communicate(timeout=20)
    values, count = delays(arrivals)
    print(f"  stalled watcher: {stalled_result}; messages per watcher: {results[0]}")
    return report("thermolab", values, count, watchers * samples)


async def bench_peer(watchers: int, seconds: float) -> dict[str, float]:
    """A bare websockets broadcast of the same message rate to the same number of clients."""
    port = free_port()
    samples = int(seconds / DT)
    connected: set[websockets.ServerConnection] = set()

    async def handler(ws: websockets.ServerConnection) -> None:
        connected.add(ws)
        try:
            await ws.wait_closed()
        finally:
            connected.discard(ws)

    done = asyncio.Event()
    async with websockets.serve(handler, "127.0.0.1", port):
        url = f"ws://127.0.0.1:{port}"
        arrivals: list[list[tuple[int, float]]] = [[] for _ in range(watchers)]
        clients = [asyncio.create_task(watch(url, {}, arrivals[i], done)) for i in range(watchers)]
        while len(connected) < watchers:
            await asyncio.sleep(0.05)
        start = time.monotonic()
        for k in range(samples):
            await asyncio.sleep(max(0.0, start + k * DT - time.monotonic()))
            text = json.dumps({"type": "tick", "k": k, "t": k * DT, "u": 5.0, "y": 0.7})
            websockets.broadcast(connected, text)
        websockets.broadcast(connected, json.dumps({"type": "end"}))
        await asyncio.wait_for(asyncio.gather(*clients), 30)
        done.set()
    values, count = delays(arrivals)
    return report("peer", values, count, watchers * samples)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--watchers", type=int, default=500)
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    print(
        f"{args.watchers} watchers, one rig at {1 / DT:g} samples/s for {args.seconds:g} s, "
        "plus one stalled watcher (delays beyond the fastest delivery seen)"
    )
    ours = asyncio.run(bench_thermolab(args.watchers, args.seconds))
    asyncio.run(bench_peer(args.watchers, args.seconds))
    if ours:
        met = ours["p99"] < 100.0 and ours["received"] > 0.999
        print(f"target (p99 < 100 ms, every sample delivered): {'met' if met else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
