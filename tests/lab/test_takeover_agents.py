"""A rig host's run lives through the owner worker's death: the standby adopts it.

Real processes on a fresh PostgreSQL schema and the loopback Redis: an owner
and a follower of a lab whose only rig is on a rig host (``agent = true``: a
follower of such a lab stands by without ``--standby``), and
``thermolab agent`` on a twin given both addresses, the follower's first. A
student starts a run through the follower; the owner is killed with SIGKILL
mid-run. The follower takes over, the agent's link moves to it (it stops
refusing), the same run goes on under the same control session, a watcher on
the follower keeps its socket and its ``seq`` never goes back, the student's
END through the follower ends the run with its method results (the
identifiers built again), and the stored samples have no gap.
Skipped, with the reason, where PostgreSQL or Redis is absent.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from sqlalchemy import select
from websockets.sync.client import connect

from thermolab.lab.db import Database
from thermolab.lab.db.models import Sample

from .fleet_setup import PEOPLE, seed_lab, start_agent, stop
from .test_takeover import TAKEN_OVER, _open_turns
from .test_workers import Worker, _start
from .test_workers_agents import LAB_TOML

pytestmark = [pytest.mark.postgres, pytest.mark.redis, pytest.mark.slow]


GRACE = "300"
"""The rig host's grace (``--agent-grace``): far above a loaded machine's takeover."""


@contextlib.contextmanager
def owner_standby_and_host(
    tmp_path: Path,
    postgres_url: str,
    redis_url: str,
    *,
    speedup: float = 1.0,
    grace: str | None = GRACE,
) -> Iterator[tuple[Worker, Worker, dict[str, str], Database]]:
    """The owner, its standby and the box's host (its twin ``speedup`` times real time);
    ``grace`` the workers' ``--agent-grace`` (``None``: the default, 30 s)."""
    cookies = seed_lab(tmp_path, postgres_url, LAB_TOML, PEOPLE, agent_rigs=["box"])
    processes: list[subprocess.Popen[bytes]] = []
    db = Database(postgres_url)
    given = () if grace is None else ("--agent-grace", grace)
    try:
        owner = _start(tmp_path, postgres_url, redis_url, *given)
        processes.append(owner.process)
        follower = _start(tmp_path, postgres_url, redis_url, *given)
        processes.append(follower.process)
        processes.append(start_agent(tmp_path, [follower.ws, owner.ws], speedup=speedup))
        yield owner, follower, cookies, db
    finally:
        stop(processes)
        db.close()


@pytest.fixture
def lab(
    tmp_path: Path, postgres_url: str, redis_url: str
) -> Iterator[tuple[Worker, Worker, dict[str, str], Database]]:
    with owner_standby_and_host(tmp_path, postgres_url, redis_url) as made:
        yield made


def wait_for(what: str, check: Any, timeout: float = 120.0) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        found = check()
        if found:
            return found
        assert time.monotonic() < deadline, f"not in time: {what}"
        time.sleep(0.5)


class Watcher(threading.Thread):
    def __init__(self, url: str, cookie: str) -> None:
        super().__init__(daemon=True)
        self.url, self.cookie = url, cookie
        self.seqs: list[int] = []
        self.ks: dict[int, list[int]] = {}
        self.error: str | None = None
        self.stop = threading.Event()

    def run(self) -> None:
        try:
            with connect(self.url, additional_headers={"Cookie": self.cookie}) as ws:
                while not self.stop.is_set():
                    try:
                        frame = json.loads(ws.recv(timeout=1.0))
                    except TimeoutError:
                        continue
                    for m in frame if isinstance(frame, list) else [frame]:
                        if "seq" in m:
                            self.seqs.append(m["seq"])
                        if m["type"] in ("sample", "samples"):
                            for item in m["items"] if m["type"] == "samples" else [m]:
                                self.ks.setdefault(item["run"], []).append(item["k"])
        except Exception as exc:  # the socket must outlive the takeover
            self.error = repr(exc)


def hosts_online(worker: Worker, cookie: str) -> bool:
    answer = httpx.get(worker.base + "/api/agents", headers={"Cookie": cookie}, timeout=30)
    assert answer.status_code in (200, 503), answer.text
    # Linked, and the health check agrees (a loaded machine may fault it for a while).
    return answer.status_code == 200 and [(h["online"], h["fault"]) for h in answer.json()] == [
        (True, None)
    ]


def test_a_rig_hosts_run_goes_on_under_the_standby_after_the_owner_is_killed(
    lab: tuple[Worker, Worker, dict[str, str], Database], tmp_path: Path
) -> None:
    owner, follower, cookies, db = lab
    ana = cookies["ana"]
    wait_for("the agent links to the owner", lambda: hosts_online(follower, cookies["tina"]))
    watcher = Watcher(follower.ws + "/api/rigs/box/live", cookies["bo"])
    watcher.start()
    with httpx.Client(base_url=follower.base, headers={"Cookie": ana}, timeout=30) as http:
        wait_for(  # 409 while the health check has the rig out of service
            "ana takes the box", lambda: http.post("/api/rigs/box/control").status_code == 200
        )
        started = http.post(
            "/api/rigs/box/runs",
            json={"dt": 0.2, "samples": 3000, "signal": "step:0:40@0.4", "methods": ["lsm"]},
        )
        assert started.status_code == 201, started.text
        run_id: int = started.json()["id"]
    (turn,) = _open_turns(db)
    wait_for("samples reach the watcher", lambda: len(watcher.ks.get(run_id, [])) >= 5)

    owner.process.send_signal(signal.SIGKILL)
    owner.process.wait()
    wait_for("the follower takes over", lambda: TAKEN_OVER in follower.log.read_text())
    before = len(watcher.ks.get(run_id, []))
    wait_for(
        "the run's samples flow again, through the new owner",
        lambda: len(watcher.ks.get(run_id, [])) >= before + 10,
    )
    assert "linked to " + follower.ws in (tmp_path / "agent.log").read_text()
    with httpx.Client(base_url=follower.base, headers={"Cookie": ana}, timeout=30) as http:
        rig = http.get("/api/rigs/box").json()
        assert rig["access"]["role"] == "controller"
        ended = http.post("/api/rigs/box/runs/current/stop")
        assert ended.status_code in (200, 202), ended.text
        run = wait_for(
            "the run's end is stored",
            lambda: (r := http.get(f"/api/runs/{run_id}").json())["status"] != "running" and r,
        )
    assert run["status"] == "stopped", run
    # Its identifiers were built again by the new owner, fed what was stored before.
    assert "lsm" in run["results"], run
    watcher.stop.set()
    watcher.join(timeout=60)
    assert watcher.error is None, watcher.error
    assert all(b > a for a, b in itertools.pairwise(watcher.seqs)), "seq went back"
    with db.read() as session:
        stored = select(Sample.k).where(Sample.run_id == run_id).order_by(Sample.k)
        ks = list(session.scalars(stored))
    assert ks == list(range(len(ks))), "a gap in the stored samples"
    assert _open_turns(db) == [turn]


def test_a_kill_of_the_owner_keeps_a_rig_hosts_run_to_its_end_with_the_default_grace(
    tmp_path: Path, postgres_url: str, redis_url: str
) -> None:
    """Issue #23, one try of benchmarks/bench_takeover.py's ten: the default grace (30 s),
    the student heartbeating through the standby, the run going on to its last sample."""
    samples = 100  # 20 s
    with owner_standby_and_host(tmp_path, postgres_url, redis_url, grace=None) as made:
        owner, standby, cookies, db = made
        wait_for("the agent links", lambda: hosts_online(standby, cookies["tina"]))
        with httpx.Client(base_url=standby.base, headers={"Cookie": cookies["ana"]}) as http:
            http.timeout = httpx.Timeout(30)
            wait_for("ana takes the box", lambda: http.post("/api/rigs/box/control").is_success)
            started = http.post(
                "/api/rigs/box/runs",
                json={"dt": 0.2, "samples": samples, "signal": "step:0:40@0.4", "methods": ["lsm"]},
            )
            assert started.status_code == 201, started.text
            run_id: int = started.json()["id"]
            (turn,) = _open_turns(db)
            wait_for("the run's first samples", lambda: _stored(db, run_id) >= 10)
            owner.process.send_signal(signal.SIGKILL)
            owner.process.wait()

            def ended() -> dict[str, Any] | None:
                http.post("/api/rigs/box/heartbeat")  # the student's page, held if need be
                run: dict[str, Any] = http.get(f"/api/runs/{run_id}").json()
                return run if run["status"] != "running" else None

            run = wait_for("the run's end is stored", ended, timeout=180)
    assert (run["status"], run["endReason"]) == ("finished", "completed"), run
    with db.read() as session:
        stored = select(Sample.k).where(Sample.run_id == run_id).order_by(Sample.k)
        assert list(session.scalars(stored)) == list(range(samples)), "a lost or doubled sample"
    assert _open_turns(db) == [turn]


def _stored(db: Database, run_id: int) -> int:
    with db.read() as session:
        return len(list(session.scalars(select(Sample.k).where(Sample.run_id == run_id))))
