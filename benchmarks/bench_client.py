"""Command round trip of a script: ``thermolab.client`` on loopback beside a local TCLab.

* **client**: ``thermolab serve`` in a child process (SQLite in a temporary
  folder, the kit's twin ``sim:tclab`` in real time). A script holding the
  turn through :class:`thermolab.client.Lab` (an API token, HTTP keep-alive)
  times ``Turn.set_input`` (``PUT /api/rigs/kit/input``: authenticated,
  checked, recorded in the database, applied) and ``Turn.read``
  (``GET /api/rigs/kit/reading``: the controller's fresh read of the device)
  — what a notebook's ``lab.Q1(...)`` and ``lab.T1`` cost against a lab rig.
* **peer**: the TCLab driver (``thermolab.rigs.TCLabRig``) over the firmware
  emulator's pseudo-terminal in this process — a kit on the student's own USB
  port, as near as this machine has one: ``rig.apply`` (``Q1`` and its echo)
  and ``rig.read`` (``T1``).

Each call is timed with ``perf_counter`` (the two kinds interleaved, after a
warm-up); it prints the median and 99th percentile in milliseconds and the
ratio client/peer.

Usage::

    .venv/bin/python benchmarks/bench_client.py                 # 1000 round trips of each
    .venv/bin/python benchmarks/bench_client.py --calls 300
"""

from __future__ import annotations

import argparse
import contextlib
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx

from thermolab.client import Lab
from thermolab.rigs import open_rig
from thermolab.rigs.clock import RealClock
from thermolab.rigs.tclab_emulator import TCLabEmulator

PASSWORD = "benchmark password 2026"
CONFIG = '[[rigs]]\nid = "kit"\ntitle = "kit twin"\nspec = "sim:tclab"\n'


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


@contextlib.contextmanager
def served_lab(
    config: str = CONFIG, serve_options: tuple[str, ...] = ()
) -> Iterator[tuple[str, str]]:
    """A lab in a child process; yields its URL and an API token of a teacher.

    ``config``: its ``lab.toml``; ``serve_options``: more ``thermolab serve``
    options (``--speedup 20``...). Also used by ``bench_tclab_notebooks.py``.
    """
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp)
        (data / "lab.toml").write_text(config, encoding="utf-8")
        base = [sys.executable, "-m", "thermolab", "--data-dir", str(data)]
        subprocess.run(
            [*base, "user", "add", "bench", "--role", "teacher", "--password-stdin"],
            input=PASSWORD + "\n",
            text=True,
            check=True,
            capture_output=True,
        )
        port = _free_port()
        serve = [*base, "serve", "--port", str(port), "--config", str(data / "lab.toml")]
        with (data / "server.log").open("wb") as log:
            server = subprocess.Popen(
                [*serve, *serve_options], stdout=log, stderr=subprocess.STDOUT
            )
            url = f"http://127.0.0.1:{port}"
            try:
                deadline = time.monotonic() + 180  # a loaded machine takes over 60 s
                while True:
                    with contextlib.suppress(httpx.HTTPError):
                        if httpx.get(f"{url}/api/version", timeout=1).status_code == 200:
                            break
                    if server.poll() is not None or time.monotonic() > deadline:
                        raise SystemExit(f"the lab did not start: {data / 'server.log'}")
                    time.sleep(0.2)
                with httpx.Client(base_url=url) as browser:
                    login = {"username": "bench", "password": PASSWORD}
                    browser.post("/api/session", json=login).raise_for_status()
                    made = browser.post("/api/tokens", json={"name": "bench"})
                    made.raise_for_status()
                yield url, made.json()["token"]
            finally:
                server.terminate()
                server.wait(timeout=30)


def timed(calls: int, *actions: Callable[[], object]) -> list[list[float]]:
    """Milliseconds of each action, interleaved, after a warm-up of 20 rounds."""
    for _ in range(20):
        for action in actions:
            action()
    times: list[list[float]] = [[] for _ in actions]
    for _ in range(calls):
        for i, action in enumerate(actions):
            start = time.perf_counter()
            action()
            times[i].append((time.perf_counter() - start) * 1e3)
    return times


def summary(values: list[float]) -> tuple[float, float]:
    ordered = sorted(values)
    p99 = ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))]
    return statistics.median(ordered), p99


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=1000, help="round trips of each kind")
    args = parser.parse_args()

    levels = [10.0, 20.0]
    with served_lab() as (url, token), Lab(url, token) as lab, lab.control("kit") as turn:
        k = iter(range(10**9))
        ours = timed(
            args.calls,
            lambda: turn.set_input(levels[next(k) % 2]),
            turn.read,
        )
    clock = RealClock()
    with (
        TCLabEmulator(clock=clock, seed=1) as emulator,
        open_rig(f"tclab:{emulator.port}", clock=clock, reset_wait=0.0) as rig,
    ):
        rig.power_on()
        j = iter(range(10**9))
        peer = timed(args.calls, lambda: rig.apply(levels[next(j) % 2]), rig.read)
        rig.power_off()

    print(f"command round trips, {args.calls} of each (ms; median / p99)")
    print(f"{'':28}{'thermolab.client':>22}{'local TCLab (pty)':>22}{'ratio':>10}")
    for name, mine, theirs in (
        ("set input (Q1)", ours[0], peer[0]),
        ("read output (T1)", ours[1], peer[1]),
    ):
        m_med, m_p99 = summary(mine)
        p_med, p_p99 = summary(theirs)
        print(
            f"{name:28}{m_med:10.3f} / {m_p99:8.3f}{p_med:10.3f} / {p_p99:8.3f}"
            f"{m_med / p_med:9.1f}x"
        )


if __name__ == "__main__":
    main()
