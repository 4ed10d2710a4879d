"""Join storm: N watchers join one rig's live stream within about a second, mid-run.

Every page of a lecture hall reconnecting after a restart, or a class opening
the rig at the bell (issue #26: "1,000 watchers joining within a second delay
no sample by more than 100 ms"). Two servers are measured in turn with the same
clients, as in ``bench_live.py`` (whose watchers, servers and lab this reuses):

* **thermolab**: ``thermolab serve`` (SQLite, the twin in real time), a
  teacher's run at 10 samples/s with LSM and WLSM;
* **peer**: the bare ``websockets`` broadcast server of ``bench_live.py``.

``--base`` watchers (50) are connected before the run, from a client process
of their own. ``--at`` seconds into it (4), the other client processes open
their share of the N joiners all at once (no waves). Every watcher comes with
one student's login (a teacher holds the controls with another), is let in,
gets its hello (thermolab) and then every sample.

Printed, in ms:

* **base, before**: the delays of the samples the base watchers got before the
  storm (the steady state);
* **base, storm**: the same from the storm's start to 1 s after the last
  joiner was let in: what the storm costs those already watching;
* **joiners**: the delays of the samples each joiner got that were taken
  after it was let in (the run's earlier samples it is sent on joining are no
  delay);
* **let in**: from a joiner's connect to its hello (thermolab) or handshake
  (peer): how long a page waits to show the rig.

A delay is as in ``bench_live.py``: arrival - (t0 + k dt), t0 the run's start
as the base watchers' earliest arrivals show it.

Usage::

    .venv/bin/python benchmarks/bench_join_storm.py                 # 1000 joiners
    .venv/bin/python benchmarks/bench_join_storm.py --joiners 300 --profile /tmp/storm
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import sys
import time
from typing import Any

from bench_live import (
    DT,
    PYTHON,
    Watcher,
    expect,
    go,
    kill,
    new_loop,
    open_watcher,
    running_lab,
    running_peer,
)

SCRIPT = os.path.abspath(__file__)
"""This script: its client processes run it with ``--role``."""


async def clients_main(url: str, cookie: str | None, base: int, joiners: int) -> None:
    """A client process: ``base`` watchers now, ``joiners`` at once on ``join`` from stdin."""
    loop = asyncio.get_running_loop()
    watchers: list[Watcher] = list(
        await asyncio.gather(*(open_watcher(url, cookie) for _ in range(base)))
    )
    print("ready", flush=True)
    await loop.run_in_executor(None, sys.stdin.readline)  # "join"
    storm_start = time.monotonic()

    async def join() -> tuple[Watcher, float, float]:
        began = time.monotonic()
        watcher = await open_watcher(url, cookie)
        return watcher, began, time.monotonic()

    joined = await asyncio.gather(*(join() for _ in range(joiners)))
    print("joined", flush=True)
    everyone = [*watchers, *(w for w, _, _ in joined)]
    _, pending = await asyncio.wait([w.ended for w in everyone], timeout=180)
    print("done", flush=True)

    def record(watcher: Watcher) -> dict[str, Any]:
        return {"k": watcher.ks.tolist(), "t": watcher.arrivals.tolist()}

    result = {
        "storm_start": storm_start,
        "base": [record(w) for w in watchers],
        "joiners": [{**record(w), "began": b, "in": i} for w, b, i in joined],
        "unfinished": len(pending),
    }
    print(json.dumps(result), flush=True)
    for watcher in everyone:
        if watcher.transport is not None:
            watcher.transport.abort()


async def start_clients(
    url: str, cookie: str | None, base: int, joiners: int, procs: int
) -> list[asyncio.subprocess.Process]:
    """One process of the base watchers, ``procs`` of the joiners (a client busy joining
    would read its base watchers' samples late: the server's delay is measured apart)."""
    shares = [(base, 0)] + [(0, joiners // procs + (i < joiners % procs)) for i in range(procs)]
    clients = []
    for base_share, joiner_share in shares:
        command = [SCRIPT, "--role", "clients", "--url", url]
        command += ["--base", str(base_share), "--joiners", str(joiner_share)]
        if cookie:
            command += ["--cookie", cookie]
        clients.append(
            await asyncio.create_subprocess_exec(
                PYTHON,
                *command,
                stdin=asyncio.subprocess.PIPE,
                stdout=asyncio.subprocess.PIPE,
                limit=2**28,
            )
        )
    for client in clients:
        await expect(client, "ready", 120)
    return clients


async def storm(clients: list[asyncio.subprocess.Process], at: float) -> list[dict[str, Any]]:
    """``at`` seconds after the run's start: the joiners join; then every client's result."""
    await asyncio.sleep(at)
    for client in clients:
        assert client.stdin is not None
        client.stdin.write(b"join\n")
    await asyncio.gather(*(client.stdin.drain() for client in clients if client.stdin))
    for client in clients:
        await expect(client, "joined", 120)
    for client in clients:
        await expect(client, "done", 240)
    results = []
    for client in clients:
        assert client.stdout is not None
        results.append(json.loads(await client.stdout.readline()))
        await client.wait()
    return results


def percentiles(values: list[float]) -> str:
    if not values:
        return "      -        -        -      (none)"
    values = sorted(values)
    p50 = values[len(values) // 2]
    p99 = values[min(len(values) - 1, int(0.99 * len(values)))]
    return f"{p50:7.1f}  {p99:7.1f}  {values[-1]:7.1f}  ({len(values)})"


def summarise(
    name: str, results: list[dict[str, Any]], samples: int, timeline: bool = False
) -> None:
    base = [w for r in results for w in r["base"]]
    joiners = [w for r in results for w in r["joiners"]]
    t0 = min(t - k * DT for w in base for k, t in zip(w["k"], w["t"], strict=True))
    start = min(r["storm_start"] for r in results)
    end = max((j["in"] for j in joiners), default=start) + 1.0

    def delays(watcher: dict[str, Any], after: float = -1e18) -> list[tuple[float, float]]:
        """(time the sample was taken, its delay in ms) of the samples taken after ``after``."""
        return [
            (t0 + k * DT, 1000.0 * (t - (t0 + k * DT)))
            for k, t in zip(watcher["k"], watcher["t"], strict=True)
            if t0 + k * DT >= after
        ]

    base_delays = [d for w in base for d in delays(w)]
    before = [d for taken, d in base_delays if taken < start]
    during = [d for taken, d in base_delays if start <= taken <= end]
    joined = [d for j in joiners for _, d in delays(j, after=j["in"])]
    let_in = [1000.0 * (j["in"] - j["began"]) for j in joiners]
    missing = sum(samples - len(w["k"]) for w in base)
    print(f"  {name}: the joiners were all in {end - 1.0 - start:.2f} s after the storm began")
    print(f"    base, before  {percentiles(before)}")
    print(f"    base, storm   {percentiles(during)}")
    print(f"    joiners       {percentiles(joined)}")
    print(f"    let in        {percentiles(let_in)}")
    worst = max(((d, taken - start) for taken, d in base_delays if start <= taken <= end))
    print(
        f"    the base's worst: {worst[0]:.0f} ms, a sample taken {worst[1]:.1f} s into the storm"
    )
    if timeline:  # each sample of the storm: its worst delay over the base watchers
        worst_of: dict[float, float] = {}
        for taken, d in base_delays:
            if start - 0.5 <= taken <= end:
                worst_of[taken] = max(d, worst_of.get(taken, d))
        print("    base's worst per sample (s into the storm: ms):")
        marks = [f"{taken - start:+.1f}:{d:.0f}" for taken, d in sorted(worst_of.items())]
        for row in range(0, len(marks), 10):
            print("     ", "  ".join(marks[row : row + 10]))
    unfinished = sum(r["unfinished"] for r in results)
    if missing or unfinished:
        print(f"    base watchers missed {missing} samples; {unfinished} watchers unfinished")


async def bench_thermolab(args: argparse.Namespace) -> None:
    samples = round(args.seconds / DT)
    clients: list[asyncio.subprocess.Process] = []
    try:
        async with running_lab(args.profile) as lab:
            clients = await start_clients(
                lab.url, lab.student_cookie, args.base, args.joiners, args.client_procs
            )
            await lab.start_run(samples)
            results = await storm(clients, args.at)
    finally:
        kill(clients)
    summarise("thermolab", results, samples, args.timeline)


async def bench_peer(args: argparse.Namespace) -> None:
    samples = round(args.seconds / DT)
    clients: list[asyncio.subprocess.Process] = []
    try:
        async with running_peer(samples) as (peer, url):
            clients = await start_clients(url, None, args.base, args.joiners, args.client_procs)
            await go(peer)
            results = await storm(clients, args.at)
    finally:
        kill(clients)
    summarise("peer", results, samples, args.timeline)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--joiners", type=int, default=1000, help="watchers joining at once (1000)")
    parser.add_argument("--base", type=int, default=50, help="watchers there before (50)")
    parser.add_argument("--at", type=float, default=4.0, help="seconds into the run (4)")
    parser.add_argument("--seconds", type=float, default=15.0, help="the run's length (15)")
    parser.add_argument("--client-procs", type=int, default=2, help="joiners' client processes (2)")
    parser.add_argument(
        "--timeline", action="store_true", help="print each storm sample's worst delay"
    )
    parser.add_argument("--only", choices=["thermolab", "peer"], help="measure one server")
    parser.add_argument(
        "--profile", metavar="FILE", help="sample thermolab's server with py-spy into FILE"
    )
    parser.add_argument("--role", choices=["clients"], help=argparse.SUPPRESS)
    parser.add_argument("--url", help=argparse.SUPPRESS)
    parser.add_argument("--cookie", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == "clients":
        new_loop().run_until_complete(clients_main(args.url, args.cookie, args.base, args.joiners))
        return 0
    print(
        f"{args.joiners} watchers join at once {args.at:g} s into a run at {1 / DT:g} samples/s "
        f"that {args.base} watch from its start; {args.client_procs} client processes; "
        f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}"
    )
    print("  ms                p50      p99      max  (samples)")
    for name, bench in (("thermolab", bench_thermolab), ("peer", bench_peer)):
        if args.only in (None, name):
            asyncio.run(bench(args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
