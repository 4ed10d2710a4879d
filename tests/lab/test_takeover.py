"""The owner worker killed, a standby takes the rigs over: the same controller, no reset.

Real processes on a fresh PostgreSQL schema and the loopback Redis: an owner,
two standby followers (``thermolab serve --broker ... --standby``) and a plain
follower. A student takes the twin and starts a run through the plain
follower; watchers on every follower follow the live stream. The owner is
killed with SIGKILL; within the lease's expiry (a deadline far above it: the
machine is loaded) exactly one standby owns (the lease row names it, one log
says it took over), the run that was going is interrupted, the same control
session still has the rig, GET and POST under ``/api/rigs`` work through every
worker, and no watcher lost its socket or saw its ``seq`` go back. An owner
that only hangs (SIGSTOP past the lease's expiry, then SIGCONT) finds its
lease taken and stops by itself; the same student still controls. Requests
made to every follower the moment the owner is killed (GET the rig, POST a
heartbeat) wait for the new owner and are answered by it, not 503. Skipped,
with the reason, where PostgreSQL or Redis is absent.
"""

from __future__ import annotations

import itertools
import json
import signal
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
from sqlalchemy import select
from websockets.sync.client import connect

from thermolab.lab.db import Database
from thermolab.lab.db.models import ControlSession, ServerLease

from .fleet_setup import PEOPLE, seed_lab, stop
from .test_workers import LAB_TOML, Worker, _start

pytestmark = [pytest.mark.postgres, pytest.mark.redis, pytest.mark.slow]


TAKEN_OVER = "this worker now owns the rigs"
"""What a promoted standby logs (lab/fleet/workers.py)."""


@dataclass
class Takeover:
    owner: Worker
    standbys: list[Worker]
    follower: Worker
    cookies: dict[str, str]
    db: Database


@pytest.fixture
def fleet(tmp_path: Path, postgres_url: str, redis_url: str) -> Iterator[Takeover]:
    cookies = seed_lab(tmp_path, postgres_url, LAB_TOML, PEOPLE)
    workers: list[Worker] = []
    db = Database(postgres_url)
    try:
        owner = _start(tmp_path, postgres_url, redis_url)
        workers.append(owner)
        standbys = [_start(tmp_path, postgres_url, redis_url, "--standby") for _ in range(2)]
        workers += standbys
        follower = _start(tmp_path, postgres_url, redis_url)
        workers.append(follower)
        yield Takeover(owner, standbys, follower, cookies, db)
    finally:
        stop([worker.process for worker in workers])
        db.close()


class SeqWatcher(threading.Thread):
    """A watcher on one worker: every ``seq`` it is given, and the runs' samples it saw."""

    def __init__(self, worker: Worker, cookie: str) -> None:
        super().__init__(daemon=True)
        self.url = worker.ws + "/api/rigs/twin/live"
        self.cookie = cookie
        self.seqs: list[int] = []
        self.samples: dict[int, int] = {}  # run -> samples seen
        self.ended: set[int] = set()
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
                        self._take(m)
        except Exception as exc:  # the socket must outlive the takeover
            self.error = repr(exc)

    def _take(self, m: dict[str, Any]) -> None:
        if "seq" in m:
            self.seqs.append(m["seq"])
        items = m["items"] if m["type"] == "samples" else [m]
        for item in items:
            if m["type"] in ("sample", "samples"):
                run = item["run"]
                self.samples[run] = self.samples.get(run, 0) + 1
        if m["type"] == "run" and m["event"] == "ended":
            self.ended.add(m["run"]["id"])


def _wait_for(what: str, check: Any, timeout: float = 120.0, state: Any = None) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        found = check()
        if found:
            return found
        assert time.monotonic() < deadline, f"not in time: {what} {state() if state else ''}"
        time.sleep(0.5)


def _open_turns(db: Database) -> list[int]:
    with db.read() as session:
        return list(
            session.scalars(select(ControlSession.id).where(ControlSession.ended_at.is_(None)))
        )


def _lease_pid(db: Database) -> int | None:
    with db.read() as session:
        lease = session.get(ServerLease, 1)
        return None if lease is None else lease.pid


def _rig(worker: Worker, cookie: str) -> httpx.Response:
    return httpx.get(worker.base + "/api/rigs/twin", headers={"Cookie": cookie}, timeout=30)


def test_killing_the_owner_hands_the_rigs_to_one_standby_with_the_same_controller(
    fleet: Takeover,
) -> None:
    ana = fleet.cookies["ana"]
    followers = [*fleet.standbys, fleet.follower]
    with httpx.Client(base_url=fleet.follower.base, headers={"Cookie": ana}, timeout=30) as http:
        assert http.post("/api/rigs/twin/control").status_code == 200
        started = http.post(
            "/api/rigs/twin/runs",
            json={"dt": 0.1, "samples": 5000, "signal": "square:4:6:0.1", "methods": ["lsm"]},
        )
        assert started.status_code == 201, started.text
        first_run: int = started.json()["id"]
    (turn,) = _open_turns(fleet.db)
    page = threading.Thread(
        target=_heartbeats, args=(fleet.follower, ana, stop := threading.Event()), daemon=True
    )
    page.start()  # ana's page, as a browser's: a heartbeat every 2 s (held while no one owns)
    watchers = [SeqWatcher(worker, fleet.cookies["bo"]) for worker in followers]
    for watcher in watchers:
        watcher.start()
    _wait_for(
        "every watcher sees the run's samples",
        lambda: all(w.samples.get(first_run, 0) >= 5 or w.error for w in watchers),
    )

    fleet.owner.process.send_signal(signal.SIGKILL)
    fleet.owner.process.wait()
    pids = {w.process.pid: w for w in fleet.standbys}
    new_owner: Worker = _wait_for(
        "a standby takes the lease", lambda: pids.get(_lease_pid(fleet.db) or -1)
    )
    # Every worker answers about the rig again (the new owner itself, the others forwarding).
    for worker in followers:
        _wait_for(f"{worker.base} answers", lambda w=worker: _rig(w, ana).status_code == 200)
    # The run that was going on the dead owner's device is interrupted, as after a restart.
    run = httpx.get(
        fleet.follower.base + f"/api/runs/{first_run}", headers={"Cookie": ana}, timeout=30
    )
    assert run.status_code == 200, run.text
    assert run.json()["status"] == "interrupted"
    # The same student, in the same turn, still has the controls, whichever worker is asked.
    assert _open_turns(fleet.db) == [turn]
    for worker in followers:
        assert _rig(worker, ana).json()["access"]["role"] == "controller"
    # POST through a worker that is not the owner: a new run, on the new owner's device.
    other = next(w for w in fleet.standbys if w is not new_owner)
    started = httpx.post(
        other.base + "/api/rigs/twin/runs",
        headers={"Cookie": ana},
        json={"dt": 0.1, "samples": 40, "signal": "square:4:6:0.1", "methods": ["lsm"]},
        timeout=30,
    )
    assert started.status_code == 201, started.text
    second_run: int = started.json()["id"]
    _wait_for(
        "every watcher sees the new run's samples and the first run's end",
        lambda: all(
            w.error or (w.samples.get(second_run, 0) >= 5 and first_run in w.ended)
            for w in watchers
        ),
        state=lambda: [(w.url, w.error, w.samples, w.ended) for w in watchers],
    )
    for watcher in watchers:
        watcher.stop.set()
    for watcher in watchers:
        watcher.join(timeout=60)
    for watcher in watchers:
        assert watcher.error is None, watcher.error  # the socket lived through the takeover
        assert all(b > a for a, b in itertools.pairwise(watcher.seqs)), "seq went back"
    # Exactly one standby took over, and it still holds the lease.
    assert _lease_pid(fleet.db) == new_owner.process.pid
    took = [w for w in fleet.standbys if TAKEN_OVER in w.log.read_text()]
    assert took == [new_owner]
    assert _open_turns(fleet.db) == [turn]
    stop.set()
    page.join(timeout=60)


def test_an_owner_that_stalled_past_its_lease_stops_and_the_standby_keeps_the_rigs(
    fleet: Takeover,
) -> None:
    ana = fleet.cookies["ana"]
    answer = httpx.post(
        fleet.follower.base + "/api/rigs/twin/control", headers={"Cookie": ana}, timeout=30
    )
    assert answer.status_code == 200, answer.text
    (turn,) = _open_turns(fleet.db)
    page = threading.Thread(
        target=_heartbeats, args=(fleet.follower, ana, stop := threading.Event()), daemon=True
    )
    # ana's page, as a browser's: a heartbeat every 2 s (those the stalled owner took and did
    # not answer are 503s: they may have been applied, the follower does not send them again)
    page.start()
    # The owner hangs (alive, not renewing): the standbys wait for the lease to run out.
    fleet.owner.process.send_signal(signal.SIGSTOP)
    pids = {w.process.pid: w for w in fleet.standbys}
    try:
        new_owner: Worker = _wait_for(
            "a standby takes the run-out lease", lambda: pids.get(_lease_pid(fleet.db) or -1)
        )
    finally:
        fleet.owner.process.send_signal(signal.SIGCONT)
    # Woken, the old owner finds the lease taken and stops (no two owners).
    _wait_for("the old owner stops", lambda: fleet.owner.process.poll() is not None)
    assert "another worker took over the rigs' lease" in fleet.owner.log.read_text()
    assert _lease_pid(fleet.db) == new_owner.process.pid
    # The ownerless gap (over the lease's 15 s) ended no turn: the same student controls.
    assert _open_turns(fleet.db) == [turn]
    for worker in [*fleet.standbys, fleet.follower]:
        rig = _wait_for(
            f"{worker.base} answers", lambda w=worker: (r := _rig(w, ana)).status_code == 200 and r
        )
        assert rig.json()["access"]["role"] == "controller"
    stop.set()
    page.join(timeout=60)


def test_requests_made_the_moment_the_owner_dies_are_answered_by_the_new_owner(
    fleet: Takeover,
) -> None:
    ana = fleet.cookies["ana"]
    taken = httpx.post(
        fleet.follower.base + "/api/rigs/twin/control", headers={"Cookie": ana}, timeout=30
    )
    assert taken.status_code == 200, taken.text
    (turn,) = _open_turns(fleet.db)
    followers = [*fleet.standbys, fleet.follower]
    for worker in followers:  # each follower has heard the owner and forwards to it
        assert _rig(worker, ana).status_code == 200
    fleet.owner.process.send_signal(signal.SIGKILL)
    fleet.owner.process.wait()
    # At once, before any standby took over: the rig, and a heartbeat (a POST that needs the
    # controls), through every follower — the one about to be promoted among them.
    answers: dict[tuple[str, str], httpx.Response | str] = {}

    def ask(worker: Worker, method: str) -> None:
        path = "/api/rigs/twin" if method == "GET" else "/api/rigs/twin/heartbeat"
        try:
            answers[worker.base, method] = httpx.request(
                method, worker.base + path, headers={"Cookie": ana}, timeout=90
            )
        except httpx.HTTPError as exc:
            answers[worker.base, method] = repr(exc)

    asking = [
        threading.Thread(target=ask, args=(worker, method))
        for worker in followers
        for method in ("GET", "POST")
    ]
    for thread in asking:
        thread.start()
    for thread in asking:
        thread.join(timeout=120)
    assert len(answers) == len(asking)
    for (base, method), answer in answers.items():
        assert isinstance(answer, httpx.Response), (base, method, answer)
        assert answer.status_code == 200, (base, method, answer.text)
        assert answer.json()["access"]["role"] == "controller"
    pids = {w.process.pid: w for w in fleet.standbys}
    assert _lease_pid(fleet.db) in pids  # answered by the new owner
    assert _open_turns(fleet.db) == [turn]


def _heartbeats(worker: Worker, cookie: str, stop: threading.Event) -> None:
    with httpx.Client(base_url=worker.base, headers={"Cookie": cookie}, timeout=30) as http:
        while not stop.wait(2.0):
            try:
                http.post("/api/rigs/twin/heartbeat")
            except httpx.HTTPError:
                continue
