"""Setting up the real-process fleet tests: the lab's accounts, a rig host, stopping it all.

Shared by the several-workers, takeover and rig-host tests (tests/lab/test_workers*.py,
test_takeover*.py), which start ``thermolab serve`` workers and ``thermolab agent``
hosts as processes on one PostgreSQL database.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from collections.abc import Iterable, Sequence
from pathlib import Path

from thermolab.lab.agents import issue_secret
from thermolab.lab.clock import SystemClock
from thermolab.lab.config import load_config
from thermolab.lab.db import Database
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.service import Lab

from .conftest import FAST_HASHER

PASSWORD = "correct horse"
#: A teacher and two students: the usual cast.
PEOPLE = (("tina", "teacher"), ("ana", "student"), ("bo", "student"))


def seed_lab(
    tmp: Path,
    postgres_url: str,
    lab_toml: str,
    people: Iterable[tuple[str, str]],
    *,
    agent_rigs: Sequence[str] = (),
) -> dict[str, str]:
    """Write ``lab.toml``, add the people (name, role) and return a session cookie each.

    Each rig of ``agent_rigs`` gets its host's secret in ``<rig>.secret``. The lab
    is closed again: the workers the test starts open it.
    """
    (tmp / "lab.toml").write_text(textwrap.dedent(lab_toml))
    config = load_config(tmp / "lab.toml", tmp).with_overrides(
        database_url=postgres_url, speedup=None
    )
    setup = Lab(config, hasher=FAST_HASHER, database=Database(postgres_url))
    setup.start()
    try:
        cookies = {}
        for name, role in people:
            setup.users.add(name, PASSWORD, role)
            token, _ = setup.sessions.create(setup.users.get(name))
            cookies[name] = f"{COOKIE_NAME}={token}"
        for rig in agent_rigs:
            secret = issue_secret(setup.db, config, SystemClock(), rig)
            (tmp / f"{rig}.secret").write_text(secret)
    finally:
        setup.close()
    return cookies


def start_agent(
    tmp: Path, labs: Sequence[str], rig: str = "box", *, speedup: float = 1.0
) -> subprocess.Popen[bytes]:
    """``thermolab agent`` for ``rig`` (a realistic twin, ``speedup`` times real time),
    dialling the ``labs`` in order."""
    dial = [arg for lab in labs for arg in ("--lab", lab)]
    with (tmp / "agent.log").open("wb") as log:
        return subprocess.Popen(
            [sys.executable, "-m", "thermolab", "agent", *dial,
             "--rig", rig, "--spec", "sim:tclab",
             "--secret-file", str(tmp / f"{rig}.secret"),
             "--outbox", str(tmp / "outbox.sqlite3"), "--speedup", str(speedup)],
            env=dict(os.environ, THERMOLAB_DATA_DIR=str(tmp)),
            stdout=log, stderr=subprocess.STDOUT,
        )  # fmt: skip


def stop(processes: Sequence[subprocess.Popen[bytes]]) -> None:
    """SIGINT each still running (the last started first), then wait; kill what hangs."""
    for process in reversed(processes):
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
    for process in reversed(processes):
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
