"""The owner worker killed with SIGKILL during a rig host's run: is the run kept?

Issue #23's "done when" for a takeover — "a kill -9 of the owner during a
remote run keeps the run in 10 of 10 tries" — measured on real processes (the
helpers of the real-process tests in ``tests/lab``): on a fresh PostgreSQL
schema and the loopback Redis, an owner and a standby worker with the
**default** grace (``--agent-grace`` not given: 30 s), and ``thermolab agent``
on a TCLab twin given both addresses (the standby's first, as the tests).
A student takes the box, starts a 30 s run and keeps her turn alive with a
heartbeat every 2 s through the standby (a browser's); at a random moment 2–12
s into the run the owner is killed with SIGKILL. A try **keeps the run** when
the run goes on under the new owner to its last sample and is stored
``finished`` ("completed") with every sample asked for and no gap in ``k``,
and the student's turn is the one she had. Printed per try: when the owner was
killed, the seconds from the kill until the new owner shows the host online
and healthy, how the run ended, its samples; then ``kept k/N``.

    .venv/bin/python benchmarks/bench_takeover.py             # 10 tries (about 10 min)
    .venv/bin/python benchmarks/bench_takeover.py --tries 2 --seed 1
    .venv/bin/python benchmarks/bench_takeover.py --hang --tries 3

``--hang``: the owner is stopped with SIGSTOP instead (killed once the standby
has taken over), as a machine gone would be: its lease lapses only after 15 s,
the longest takeover the default grace must outlive.

Needs PostgreSQL and Redis on loopback (THERMOLAB_TEST_POSTGRES_URL and
THERMOLAB_TEST_REDIS_URL as the tests read them).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
from sqlalchemy import create_engine, select, text
from sqlalchemy.engine import make_url

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
# The tests' services (tests/conftest.py's defaults): a schema of its own, a Redis prefix.
os.environ.setdefault(
    "THERMOLAB_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
)
os.environ.setdefault("THERMOLAB_TEST_REDIS_URL", "redis://127.0.0.1:6379/11")
from lab.conftest import REDIS_URL, postgres_base_url
from lab.fleet_setup import PEOPLE, seed_lab, start_agent, stop
from lab.test_workers import Worker, _start
from thermolab.lab.db import Database
from thermolab.lab.db.models import ControlSession, Sample

DT = 0.2
SAMPLES = 150  # 30 s
TAKEN_OVER = "this worker now owns the rigs"  # what a promoted standby logs
TOML = """
[access]
login_attempts_per_address = 1000

[rig_defaults]
control_time_limit = 3600
idle_limit = 0
power_off_grace = 600

[[rigs]]
id = "box"
title = "Box"
spec = "sim:tclab"
agent = true
"""


@contextlib.contextmanager
def _schema() -> Iterator[str]:
    """A fresh schema on the test server, as a URL whose search_path points to it."""
    server = postgres_base_url()
    name = f"thermolab_bench_{uuid.uuid4().hex[:12]}"
    admin = create_engine(server, isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text(f'CREATE SCHEMA "{name}"'))
    url = make_url(server).update_query_dict({"options": f"-csearch_path={name}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP SCHEMA "{name}" CASCADE'))
        admin.dispose()


def _until(what: str, check: Callable[[], Any], timeout: float) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        found = check()
        if found:
            return found
        if time.monotonic() > deadline:
            raise TimeoutError(what)
        time.sleep(0.2)


def _linked(worker: Worker, cookie: str) -> bool:
    answer = httpx.get(worker.base + "/api/agents", headers={"Cookie": cookie}, timeout=30)
    return answer.status_code == 200 and [(h["online"], h["fault"]) for h in answer.json()] == [
        (True, None)
    ]


def _heartbeat(base: str, cookie: str, stop_beating: threading.Event) -> None:
    """A browser's heartbeat: every 2 s, whatever answers (held through the takeover)."""
    while not stop_beating.wait(2.0):
        with contextlib.suppress(httpx.HTTPError):
            httpx.post(base + "/api/rigs/box/heartbeat", headers={"Cookie": cookie}, timeout=30)


def _try(tmp: Path, rng: random.Random, *, hang: bool = False) -> dict[str, Any]:
    with _schema() as url:
        cookies = seed_lab(tmp, url, TOML, PEOPLE, agent_rigs=["box"])
        processes: list[subprocess.Popen[bytes]] = []
        db = Database(url)
        beating = threading.Event()
        try:
            owner = _start(tmp, url, REDIS_URL)
            processes.append(owner.process)
            standby = _start(tmp, url, REDIS_URL)
            processes.append(standby.process)
            processes.append(start_agent(tmp, [standby.ws, owner.ws]))
            _until("the host links", lambda: _linked(standby, cookies["tina"]), 120)
            ana = httpx.Client(
                base_url=standby.base, headers={"Cookie": cookies["ana"]}, timeout=60
            )
            _until("ana takes the box", lambda: ana.post("/api/rigs/box/control").is_success, 120)
            with db.read() as session:
                turn = session.scalar(
                    select(ControlSession.id).where(ControlSession.ended_at.is_(None))
                )
            started = ana.post(
                "/api/rigs/box/runs",
                json={"dt": DT, "samples": SAMPLES, "signal": "step:0:40@0.4", "methods": ["lsm"]},
            )
            assert started.status_code == 201, started.text
            run_id = started.json()["id"]
            threading.Thread(
                target=_heartbeat, args=(standby.base, cookies["ana"], beating), daemon=True
            ).start()
            _until("the first sample", lambda: _stored(db, run_id), 60)
            kill_at = rng.uniform(2.0, 12.0)
            time.sleep(kill_at)
            owner.process.send_signal(signal.SIGSTOP if hang else signal.SIGKILL)
            killed = time.monotonic()
            if not hang:
                # Reaped at once, as systemd reaps its units: an unreaped zombie's pid still
                # answers, and the standby would wait for the lease's 15 s as for a hang.
                owner.process.wait()
            _until("the standby takes over", lambda: TAKEN_OVER in standby.log.read_text(), 60)
            owner.process.kill()  # a hung owner's machine never comes back either
            owner.process.wait()
            _until("the host links to it", lambda: _linked(standby, cookies["tina"]), 120)
            relinked = time.monotonic() - killed
            run = _until(
                "the run's end is stored",
                lambda: (r := ana.get(f"/api/runs/{run_id}").json())["status"] != "running" and r,
                SAMPLES * DT + 120,
            )
            with db.read() as session:
                ks = list(
                    session.scalars(
                        select(Sample.k).where(Sample.run_id == run_id).order_by(Sample.k)
                    )
                )
                turns = list(
                    session.scalars(
                        select(ControlSession.id).where(ControlSession.ended_at.is_(None))
                    )
                )
            ana.close()
            kept = run["status"] == "finished" and ks == list(range(SAMPLES)) and turns == [turn]
            return {"kill_at": kill_at, "relinked": relinked, "run": run, "ks": len(ks),
                    "turn_kept": turns == [turn], "kept": kept}  # fmt: skip
        finally:
            beating.set()
            stop(processes)
            db.close()


def _stored(db: Database, run_id: int) -> bool:
    with db.read() as session:
        return session.scalar(select(Sample.k).where(Sample.run_id == run_id).limit(1)) is not None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tries", type=int, default=10)
    parser.add_argument("--seed", type=int, default=None, help="of the kill moments")
    parser.add_argument("--hang", action="store_true", help="SIGSTOP the owner (lease lapses)")
    parser.add_argument("--logs", type=Path, default=None, help="keep each try's logs here")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    kept = 0
    for n in range(1, args.tries + 1):
        with tempfile.TemporaryDirectory(prefix="bench-takeover-") as tmp:
            try:
                got = _try(Path(tmp), rng, hang=args.hang)
            except (AssertionError, TimeoutError, httpx.HTTPError) as exc:
                print(f"try {n}: FAILED before its end: {exc!r}", flush=True)
                for log in sorted(Path(tmp).glob("*.log")):
                    print(
                        f"--- {log.name} (tail)\n" + "\n".join(log.read_text().splitlines()[-15:])
                    )
                continue
            finally:
                if args.logs is not None:
                    kept_logs = args.logs / f"try-{n}"
                    kept_logs.mkdir(parents=True, exist_ok=True)
                    for log in Path(tmp).glob("*.log"):
                        shutil.copy(log, kept_logs / log.name)
        kept += got["kept"]
        run = got["run"]
        print(
            f"try {n}: owner {'stopped' if args.hang else 'killed'} {got['kill_at']:.1f} s into "
            f"the run; host online at the new owner "
            f"{got['relinked']:.1f} s later; run {run['status']} ({run.get('endReason')}), "
            f"{got['ks']}/{SAMPLES} samples, turn kept: {got['turn_kept']} -> "
            f"{'KEPT' if got['kept'] else 'LOST'}",
            flush=True,
        )
    print(f"kept {kept}/{args.tries}")
    return 0 if kept == args.tries else 1


if __name__ == "__main__":
    sys.exit(main())
