"""One server per database: a second ``thermolab serve`` refuses to start.

The first server is a lab in this test process holding the lease (as
``thermolab serve`` does); the second is a real ``thermolab serve`` process on
the same database, on SQLite and PostgreSQL. It must exit at once with one
line, before start-up ends the first server's turns or runs.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from datetime import timedelta
from pathlib import Path

import pytest

from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import LabConfig, RigConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import ServerLease
from thermolab.lab.fleet.lease import LEASE_TTL, DatabaseLease, LeaseHeldError
from thermolab.lab.service import Lab

from .conftest import FAST_HASHER, PASSWORD


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def _serving_lab(tmp_path: Path, database_url: str, clock: ManualClock | None) -> Lab:
    config = LabConfig(
        data_dir=tmp_path, rigs=(RigConfig("twin", "Twin", "sim"),), database_url=database_url
    )
    lab = Lab(
        config,
        clock=clock,
        hasher=FAST_HASHER,
        database=Database(database_url),
        exclusive=True,
    )
    lab.start()
    return lab


def _sweep_while(lab: Lab, serving: threading.Event, controller: Principal) -> None:
    while serving.is_set():
        # The controller's page keeps its turn alive, as a browser does: else the sweep
        # itself would end it (client gone) when the second server is slow to answer.
        lab.access.heartbeat("twin", controller)
        lab.sweep()
        time.sleep(1.0)  # a server's sweep interval (lab/http/app.py)


def test_a_second_server_on_a_served_database_refuses_to_start(
    tmp_path: Path, database_url: str
) -> None:
    # The real clock: the second process compares the lease with its own.
    first = _serving_lab(tmp_path, database_url, None)
    try:
        info = first.users.add("ana", PASSWORD, "student")
        ana = Principal(info.id, info.username, info.role)
        first.access.request_control("twin", ana)
        command = [
            sys.executable,
            "-m",
            "thermolab.cli",
            "--data-dir",
            str(tmp_path / "second"),
            "serve",
            "--database-url",
            database_url,
            "--port",
            str(_free_port()),
        ]
        # The first sweeps as its server does, renewing its lease: on a loaded machine the
        # second took longer than the lease's 15 s to start, found it expired and served.
        serving = threading.Event()
        sweeper = threading.Thread(target=_sweep_while, args=(first, serving, ana))
        serving.set()
        sweeper.start()
        try:
            with subprocess.Popen(
                command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
            ) as process:
                # Generous: once a loaded CI machine had no answer in 60 s; what the process
                # said by then tells whether it was slow or serving.
                try:
                    _, stderr = process.communicate(timeout=150)
                except subprocess.TimeoutExpired:
                    process.kill()
                    _, stderr = process.communicate()
                    pytest.fail(f"the second server neither refused nor ended: {stderr}")
        finally:
            serving.clear()
            sweeper.join()
        second = subprocess.CompletedProcess(command, process.returncode, "", stderr)
        assert second.returncode != 0
        # One line for the refusal (the test's database file was made by a copy, so
        # the server may first warn that it tightened its permissions).
        lines = [x for x in second.stderr.strip().splitlines() if not x.startswith("warning:")]
        assert len(lines) == 1, second.stderr
        assert "is already served by process" in lines[0]
        assert "Traceback" not in second.stderr
        # The first server's turn was left alone (start-up never ran in the second).
        controller = first.access.snapshot("twin").controller
        assert controller is not None
        assert controller.user_id == ana.user_id
    finally:
        first.close()
    # Once the first has stopped, a server starts.
    again = _serving_lab(tmp_path, database_url, None)
    again.close()


def test_the_lease_is_taken_over_only_when_its_holder_is_gone(
    tmp_path: Path, database_url: str, clock: ManualClock
) -> None:
    first = _serving_lab(tmp_path, database_url, clock)
    rival = DatabaseLease(first.db, clock)
    with pytest.raises(LeaseHeldError):
        rival.acquire()
    clock.advance(LEASE_TTL.total_seconds() / 2)
    first.sweep()  # the holder renews
    clock.advance(LEASE_TTL.total_seconds() / 2 + 1)
    with pytest.raises(LeaseHeldError):
        rival.acquire()
    # The holder stops renewing (hung, or on another host): after the TTL it is taken over.
    clock.advance(LEASE_TTL.total_seconds() + 1)
    rival.acquire()
    assert first.lease is not None
    assert not first.lease.renew()
    # A holder of this host that no longer exists is replaced at once.
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    with first.db.write() as session:
        lease = session.get(ServerLease, 1)
        assert lease is not None
        lease.pid = int(dead.stdout)
        lease.token = "someone-else"
        lease.expires_at = clock.now() + timedelta(hours=1)
    rival.acquire()
    first.close()
    rival.release()
