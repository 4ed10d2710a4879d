"""Killing the server mid-run (SIGKILL) loses at most about a second of samples.

A real ``thermolab serve`` in a child process samples the twin at 10 Hz in
real time while a WebSocket watcher notes the last sample it saw; the server
is killed without warning, and the database must hold every sample up to one
second before that last one. Starting the lab again marks the run
interrupted and keeps what was stored.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import pytest
from websockets.sync.client import connect

from thermolab.lab.accounts.users import UserService
from thermolab.lab.clock import SystemClock
from thermolab.lab.config import load_config
from thermolab.lab.db import Database
from thermolab.lab.service import Lab

from .conftest import FAST_HASHER, PASSWORD

CONFIG = """
[rig_defaults]
idle_limit = 0

[[rigs]]
id = "twin"
title = "Twin"
spec = "sim"
"""


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


@pytest.mark.slow
def test_a_killed_server_loses_at_most_a_second_of_the_run(tmp_path: Path) -> None:
    config_file = tmp_path / "lab.toml"
    config_file.write_text(CONFIG)
    database = tmp_path / "thermolab.sqlite3"
    db = Database(f"sqlite:///{database}")
    db.upgrade()
    UserService(db, SystemClock(), FAST_HASHER).add("ana", PASSWORD, "student")
    db.close()
    port = _free_port()
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "thermolab",
            "--data-dir",
            str(tmp_path),
            "serve",
            "--port",
            str(port),
            "--config",
            str(config_file),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        base = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 60
        while True:
            with contextlib.suppress(httpx.HTTPError):
                httpx.get(base + "/openapi.json", timeout=1)
                break
            assert time.monotonic() < deadline, "the server did not start"
            time.sleep(0.1)
        url = f"ws://127.0.0.1:{port}/api/rigs/twin/live"
        seen: list[int] = []
        # A loaded CI machine answered a request after more than httpx's default 5 s.
        with httpx.Client(base_url=base, timeout=30) as http:
            login = http.post("/api/session", json={"username": "ana", "password": PASSWORD})
            login.raise_for_status()
            cookie = f"thermolab_session={http.cookies['thermolab_session']}"
            http.post("/api/rigs/twin/control").raise_for_status()
            with connect(url, additional_headers={"Cookie": cookie}) as ws:
                ws.recv()  # hello

                def watch() -> None:
                    with contextlib.suppress(Exception):
                        for text in ws:
                            if '"type":"sample"' in str(text) and '"run":null' not in str(text):
                                seen.append(int(str(text).split('"k":')[1].split(",")[0]))

                watcher = threading.Thread(target=watch, daemon=True)
                watcher.start()
                run = http.post(
                    "/api/rigs/twin/runs",
                    json={
                        "dt": 0.1,
                        "samples": 1000,
                        "signal": "step:0:10@0.5",
                        "methods": ["lsm"],
                    },
                )
                run.raise_for_status()
                while len(seen) < 20:  # two seconds of sampling
                    time.sleep(0.05)
                server.send_signal(signal.SIGKILL)
                server.wait(timeout=30)
                watcher.join(timeout=5)
        last_seen = max(seen)
    finally:
        if server.poll() is None:
            os.kill(server.pid, signal.SIGKILL)
            server.wait()
    # Restart: the lab finds the run interrupted, with what had reached the store.
    lab = Lab(load_config(config_file, tmp_path), database=Database(f"sqlite:///{database}"))
    lab.start()
    record = lab.runs.record(run.json()["id"])
    lab.close()
    assert record.status == "interrupted"
    stored = record.samples_stored
    assert stored >= last_seen + 1 - 10, (stored, last_seen)  # at most one second (10 samples) lost
