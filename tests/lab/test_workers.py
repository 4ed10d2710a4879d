"""Several ``thermolab serve`` workers on one PostgreSQL database and one Redis bus.

Real processes: two workers (``python -m thermolab serve --broker redis://...``)
on a fresh PostgreSQL schema; the first owns the rigs, the second follows
(:mod:`thermolab.lab.fleet.workers`). A watcher on the follower sees a run driven
through the owner; the follower killed with SIGKILL under load, its watchers
resume on the owner with ``since`` and miss no sample, and the controller is
unchanged; 100 students racing for control over both workers get one
controller. Skipped, with the reason, where PostgreSQL or Redis is absent.
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
from websockets.exceptions import InvalidMessage
from websockets.sync.client import ClientConnection, connect

from .fleet_setup import seed_lab, stop

pytestmark = [pytest.mark.postgres, pytest.mark.redis, pytest.mark.slow]

STUDENTS = 100

# A client silent for 15 s loses its place: on a loaded CI machine a hundred students'
# race and its check can take longer than that, so these fleets wait 5 minutes (the
# timeout itself is tested in-process, on a manual clock: tests/lab/test_access.py).
LAB_TOML = """
[access]
client_timeout = 300
login_attempts_per_address = 100000
live_sockets_per_login = 100
live_sockets_per_rig = 1000

[rig_defaults]
control_time_limit = 3600
idle_limit = 0

[[rigs]]
id = "twin"
title = "Twin"
spec = "sim:paper-practical"
"""


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


@dataclass
class Worker:
    process: subprocess.Popen[bytes]
    base: str
    log: Path

    @property
    def ws(self) -> str:
        return self.base.replace("http", "ws", 1)


@dataclass
class Fleet:
    owner: Worker
    follower: Worker
    cookies: dict[str, str]


def _start(tmp: Path, url: str, broker: str | None, *more: str) -> Worker:
    port = _free_port()
    env = dict(os.environ, THERMOLAB_DATA_DIR=str(tmp))
    log = tmp / f"worker-{port}.log"
    with log.open("wb") as err:
        process = _popen(tmp, url, broker, port, env, err, *more)
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 90
    while True:
        if process.poll() is not None:
            raise AssertionError(f"the worker stopped: {log.read_text()}")
        try:
            httpx.get(base + "/api/version", timeout=1.0)
            return Worker(process, base, log)
        except httpx.HTTPError:
            assert time.monotonic() < deadline, "the worker did not start"
            time.sleep(0.2)


def _popen(
    tmp: Path, url: str, broker: str | None, port: int, env: dict[str, str], err: Any, *more: str
) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "thermolab",
            "serve",
            "--port",
            str(port),
            "--config",
            str(tmp / "lab.toml"),
            "--database-url",
            url,
            *(["--broker", broker] if broker else []),
            *more,
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=err,
    )


@pytest.fixture
def fleet(tmp_path: Path, postgres_url: str, redis_url: str) -> Iterator[Fleet]:
    people = [("tina", "teacher")] + [(f"s{i}", "student") for i in range(STUDENTS)]
    cookies = seed_lab(tmp_path, postgres_url, LAB_TOML, people)
    owner = _start(tmp_path, postgres_url, redis_url)
    workers = [owner]
    try:
        follower = _start(tmp_path, postgres_url, redis_url)
        workers.append(follower)
        yield Fleet(owner, follower, cookies)
    finally:
        stop([worker.process for worker in workers])


def _frames(ws: ClientConnection, timeout: float) -> list[dict[str, Any]]:
    frame = json.loads(ws.recv(timeout=timeout))
    return frame if isinstance(frame, list) else [frame]


class Watcher(threading.Thread):
    """A watcher that follows a run's samples and, when its worker dies, resumes elsewhere."""

    def __init__(self, urls: list[str], cookie: str, run: int, samples: int) -> None:
        super().__init__(daemon=True)
        self.urls, self.cookie, self.run_id, self.samples = urls, cookie, run, samples
        self.ks: list[int] = []
        self.moves = 0
        self.error: str | None = None

    def run(self) -> None:
        since: int | None = None
        deadline = time.monotonic() + 120
        try:
            while time.monotonic() < deadline and (not self.ks or self.ks[-1] < self.samples - 1):
                url = self.urls[min(self.moves, len(self.urls) - 1)] + "/api/rigs/twin/live"
                if since is not None:
                    url += f"?since={since}"
                try:
                    with connect(url, additional_headers={"Cookie": self.cookie}) as ws:
                        while not self.ks or self.ks[-1] < self.samples - 1:
                            for m in _frames(ws, 30):
                                items = m["items"] if m["type"] == "samples" else [m]
                                for item in items:
                                    if m["type"] in ("sample", "samples") and (
                                        item.get("run") == self.run_id
                                        and (not self.ks or item["k"] > self.ks[-1])
                                    ):
                                        self.ks.append(item["k"])
                                if "seq" in m or (m["type"] == "hello" and since is None):
                                    since = m["seq"]
                except (OSError, EOFError, TimeoutError, InvalidMessage) as exc:
                    # InvalidMessage: the worker died during the handshake (a loaded machine
                    # had not connected every watcher in the 3 s before the kill).
                    self.moves += 1
                    if self.moves > 3:
                        raise AssertionError(f"too many reconnections: {exc!r}") from exc
                    time.sleep(0.2)
                except Exception as exc:  # a closed connection: move on
                    if type(exc).__name__.startswith("Connection"):
                        self.moves += 1
                        time.sleep(0.2)
                        continue
                    raise
        except Exception as exc:
            self.error = repr(exc)


def _start_run(base: str, cookie: str, samples: int) -> int:
    with httpx.Client(base_url=base, headers={"Cookie": cookie}, timeout=30) as http:
        taken = http.post("/api/rigs/twin/control")
        assert taken.status_code == 200, taken.text
        started = http.post(
            "/api/rigs/twin/runs",
            json={"dt": 0.1, "samples": samples, "signal": "square:4:6:0.1", "methods": ["lsm"]},
        )
        assert started.status_code == 201, started.text
        run_id: int = started.json()["id"]
        return run_id


def _controller(base: str, cookie: str) -> Any:
    rig = httpx.get(base + "/api/rigs/twin", headers={"Cookie": cookie}, timeout=30).json()
    return rig["access"].get("controller")


def test_a_watcher_on_the_follower_sees_a_run_driven_through_the_owner(fleet: Fleet) -> None:
    tina = fleet.cookies["tina"]
    watcher_url = fleet.follower.ws + "/api/rigs/twin/live"
    with connect(watcher_url, additional_headers={"Cookie": fleet.cookies["s1"]}) as ws:
        hello = _frames(ws, 30)[0]
        assert hello["type"] == "hello"
        assert hello["rig"]["input"]["live"] is True  # the owner's device, as announced
        run_id = _start_run(fleet.owner.base, tina, 30)
        ks: list[int] = []
        seqs: list[int] = []
        while len(ks) < 10:
            for m in _frames(ws, 30):
                if m["type"] == "sample" and m["run"] == run_id:
                    ks.append(m["k"])
                    seqs.append(m["seq"])
        assert ks == list(range(ks[0], ks[0] + len(ks)))
        assert all(b > a for a, b in itertools.pairwise(seqs))
    # A watcher arriving now at the follower is told of the run going (from the store).
    with connect(watcher_url, additional_headers={"Cookie": fleet.cookies["s2"]}) as late:
        assert _frames(late, 30)[0]["run"]["id"] == run_id
    # A request about the rig made to the follower is the owner's answer.
    assert _controller(fleet.follower.base, tina) == _controller(fleet.owner.base, tina)
    assert _controller(fleet.follower.base, tina) is not None
    # A browser's request (its Origin the address it reached) passes the owner's guard.
    beat = httpx.post(
        fleet.follower.base + "/api/rigs/twin/heartbeat",
        headers={"Cookie": tina, "Origin": fleet.follower.base},
        timeout=30,
    )
    assert beat.status_code in (200, 204), beat.text
    stranger = httpx.post(
        fleet.follower.base + "/api/rigs/twin/heartbeat",
        headers={"Cookie": tina, "Origin": "http://evil.example"},
        timeout=30,
    )
    assert stranger.status_code == 403


def test_killing_a_worker_moves_its_watchers_with_no_gap_and_the_same_controller(
    fleet: Fleet,
) -> None:
    tina = fleet.cookies["tina"]
    samples = 80
    run_id = _start_run(fleet.follower.base, tina, samples)  # forwarded to the owner
    before = _controller(fleet.owner.base, tina)
    watchers = [
        Watcher([fleet.follower.ws, fleet.owner.ws], fleet.cookies[f"s{i}"], run_id, samples)
        for i in range(20)
    ]
    for watcher in watchers:
        watcher.start()
    time.sleep(3.0)
    fleet.follower.process.send_signal(signal.SIGKILL)
    fleet.follower.process.wait()
    for watcher in watchers:
        watcher.join(timeout=150)
    for watcher in watchers:
        assert watcher.error is None, watcher.error
        assert watcher.moves >= 1
        assert watcher.ks == list(range(watcher.ks[0], samples)), "a gap in a watcher's data"
        assert watcher.ks[0] <= 20
    assert _controller(fleet.owner.base, tina) == before


def test_a_hundred_students_racing_for_control_over_both_workers_get_one_controller(
    fleet: Fleet,
) -> None:
    results: list[int] = []
    lock = threading.Lock()
    barrier = threading.Barrier(STUDENTS)

    def race(i: int) -> None:
        worker = fleet.owner if i % 2 else fleet.follower
        with httpx.Client(base_url=worker.base, timeout=60) as http:
            barrier.wait()
            answer = http.post("/api/rigs/twin/control", headers={"Cookie": fleet.cookies[f"s{i}"]})
        with lock:
            results.append(answer.status_code)

    threads = [threading.Thread(target=race, args=(i,)) for i in range(STUDENTS)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=120)
    assert len(results) == STUDENTS
    assert all(status in (200, 409) for status in results), results
    controllers = set()
    for i in range(STUDENTS):
        rig = httpx.get(
            fleet.follower.base + "/api/rigs/twin",
            headers={"Cookie": fleet.cookies[f"s{i}"]},
            timeout=30,
        ).json()
        if rig["access"]["role"] == "controller":
            controllers.add(f"s{i}")
    assert len(controllers) == 1
    assert {_controller(fleet.owner.base, fleet.cookies["tina"])} == controllers


def test_a_worker_with_a_broker_refuses_a_database_served_by_a_lone_server(
    tmp_path: Path, postgres_url: str, redis_url: str
) -> None:
    (tmp_path / "lab.toml").write_text(textwrap.dedent(LAB_TOML))
    alone = _start(tmp_path, postgres_url, None)
    try:
        second = subprocess.run(
            [sys.executable, "-m", "thermolab", "serve", "--port", str(_free_port()),
             "--config", str(tmp_path / "lab.toml"), "--database-url", postgres_url,
             "--broker", redis_url],
            env=dict(os.environ, THERMOLAB_DATA_DIR=str(tmp_path)),
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert second.returncode == 1
        (line,) = second.stderr.strip().splitlines()
        assert "is already served by process" in line
        assert "does not announce itself on the broker" in line
    finally:
        alone.process.send_signal(signal.SIGINT)
        alone.process.wait(timeout=30)
