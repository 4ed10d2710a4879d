"""A remote rig across a 60 s link loss: samples lost (must be 0) and time until it is back.

Starts real processes, as ``tests/agent/test_fleet.py`` does (its helpers,
``tests/agent/fleet.py``): ``thermolab serve`` with TLS (a CA made here),
one remote rig (``agent = true``, a TCLab twin driven by ``thermolab agent``)
and one in-process twin of the same kind. Both run a 10 samples/s run; after
``--before`` seconds the lab is paused (SIGSTOP: the link is dead, TCP stays
up, so the agent must notice by its own pings) for ``--loss`` seconds of wall
time, then resumed. The agent's grace is longer than the loss, so its run
goes on alone and buffers every sample in its outbox.

Printed: the samples the remote run took and the lab stored (by ``k``: gaps,
duplicates), those taken during the loss, the time from SIGCONT until the
rig is online and healthy and until the backlog is stored; and the peer, in
the same run: the store lag of the in-process rig's samples against the
remote rig's while the link is up (how far behind wall time the stored
sample count is, sampled every 0.2 s).

    .venv/bin/python benchmarks/bench_agent.py              # 60 s loss
    .venv/bin/python benchmarks/bench_agent.py --loss 10    # quicker
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path

import httpx

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "agent"))
from fleet import Fleet, make_fleet

DT = 0.1
TOML = """
[rig_defaults]
power_off_grace = 600
idle_limit = 600
control_time_limit = 3600

[access]
client_timeout = 600

[[rigs]]
id = "box"
spec = "sim:tclab"
agent = true

[[rigs]]
id = "local"
spec = "sim:tclab"
"""


def _start(client: httpx.Client, rig: str, samples: int) -> tuple[int, float]:
    assert client.post(f"/api/rigs/{rig}/control").status_code == 200
    answer = client.post(
        f"/api/rigs/{rig}/runs",
        json={"dt": DT, "samples": samples, "signal": "step:0:40@1", "methods": ["srm"]},
    )
    assert answer.status_code == 201, answer.text
    body = answer.json()
    started = datetime.fromisoformat(body["startedAt"].replace("Z", "+00:00")).timestamp()
    return int(body["id"]), started


def _lag(client: httpx.Client, run_id: int, started: float) -> float:
    stored = client.get(f"/api/runs/{run_id}").json()["samplesStored"]
    return max(0.0, (time.time() - started) - stored * DT)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loss", type=float, default=60.0, help="seconds the link is dead (60)")
    parser.add_argument("--before", type=float, default=10.0, help="seconds linked first (10)")
    args = parser.parse_args()
    samples = int((args.before + args.loss + 15) / DT)
    with tempfile.TemporaryDirectory() as tmp:
        fleet: Fleet = make_fleet(Path(tmp), TOML)
        try:
            fleet.start_lab(fleet.cert, fleet.key, grace=args.loss + 120)  # type: ignore[attr-defined]
            fleet.start_agent("box", "sim:tclab")
            with (
                contextlib.closing(fleet.client("tina")) as tina,
                contextlib.closing(fleet.client("ana")) as ana,
            ):
                fleet.wait_online(tina, "box")
                remote, remote_t0 = _start(ana, "box", samples)
                local, local_t0 = _start(tina, "local", samples)
                lags: dict[str, list[float]] = {"remote": [], "local": []}
                until = time.monotonic() + args.before
                while time.monotonic() < until:
                    lags["remote"].append(_lag(ana, remote, remote_t0))
                    lags["local"].append(_lag(tina, local, local_t0))
                    time.sleep(0.2)
                fleet.pause_lab()
                paused = time.time()
                time.sleep(args.loss)
                fleet.resume_lab()
                resumed = time.time()
                back = fleet.wait_online(tina, "box", timeout=120)
                while True:  # the backlog: every sample taken until the link returned
                    record = ana.get(f"/api/runs/{remote}").json()
                    if record["samplesStored"] * DT >= resumed - remote_t0 - 0.5:
                        break
                    time.sleep(0.05)
                drained = time.time() - resumed
                while record["status"] == "running":
                    time.sleep(0.2)
                    record = ana.get(f"/api/runs/{remote}").json()
                export = ana.get(f"/api/runs/{remote}/export.json").json()["samples"]
        finally:
            fleet.stop()
    ks = [int(k) for k in export["k"]]
    ts = [float(t) for t in export["t"]]
    gaps = (max(ks) + 1 - len(set(ks))) if ks else 0
    doubled = len(ks) - len(set(ks))
    during = sum(1 for t in ts if paused - remote_t0 <= t <= resumed - remote_t0)
    print(
        f"link loss {resumed - paused:.1f} s (lab paused by SIGSTOP), grace {args.loss + 120:g} s"
    )
    print(f"remote run: {record['status']} ({record.get('endReason')}), {len(ks)} samples stored")
    print(
        f"  samples lost (gaps in k): {gaps}   stored twice: {doubled}   "
        f"taken during the loss and stored: {during} (expected ~{(resumed - paused) / DT:.0f})"
    )
    print(
        f"  rig back online and healthy {back:.2f} s after the link returned; "
        f"backlog stored {drained:.2f} s after"
    )
    for name in ("remote", "local"):
        values = sorted(lags[name])
        print(
            f"  store lag while linked, {name:6s}: median {statistics.median(values):.3f} s, "
            f"max {values[-1]:.3f} s  ({len(values)} polls)"
        )
    return 0 if gaps == 0 and doubled == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
