"""A real ``thermolab serve`` for the client tests: kits' twins and the paper's box at 20×.

Accounts are made with ``thermolab user add`` and tokens through the HTTP API
(a password login, as in the browser), so every test talks to the lab the way
a script does: HTTP and WebSockets on loopback, nothing injected.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

PASSWORD = "a long enough password"
SPEEDUP = 20.0  # a lab second is 50 ms: a step of a notebook loop fits on a busy machine
LAB_TOML = """
[rig_defaults]
power_off_grace = 600

[[rigs]]
id = "kit"
title = "TCLab kit's twin"
spec = "sim:tclab"

[[rigs]]
id = "box"
title = "The paper's box"
spec = "sim"

[[rigs]]
id = "kit2"
title = "Another kit's twin (heated by the turn tests, so the kit starts cool elsewhere)"
spec = "sim:tclab"

[[rigs]]
id = "dual"
title = "The kit's two-heater twin"
spec = "sim:kit"

[[rigs]]
id = "brief"
title = "A kit's twin with 12 s turns (a script's turn outlives it only by extensions)"
spec = "sim:tclab"
control_time_limit = 12

[[rigs]]
id = "brief2"
title = "Another kit's twin with 12 s turns (cut once someone waits)"
spec = "sim:tclab"
control_time_limit = 12
"""
BRIEF_TURN = 12.0
"""Seconds (real) of a turn at rigs ``brief`` and ``brief2`` before any extension."""


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


@dataclass
class ServedLab:
    """A running lab: its URL, data folder and a way to make tokens."""

    url: str
    data_dir: Path

    def cookie_client(self, username: str) -> httpx.Client:
        """An HTTP client logged in with a password (the browser's way)."""
        client = httpx.Client(base_url=self.url, timeout=10)
        answer = client.post("/api/session", json={"username": username, "password": PASSWORD})
        assert answer.status_code == 200, answer.text
        return client

    def token(self, username: str, *, read_only: bool = False) -> tuple[int, str]:
        """A new API token of ``username``: (id, secret)."""
        with contextlib.closing(self.cookie_client(username)) as client:
            made = client.post("/api/tokens", json={"name": "test", "readOnly": read_only})
            assert made.status_code == 201, made.text
            return made.json()["id"], made.json()["token"]


def _thermolab(data_dir: Path, *args: str, stdin: str | None = None) -> None:
    subprocess.run(
        [sys.executable, "-m", "thermolab", "--data-dir", str(data_dir), *args],
        input=stdin,
        text=True,
        check=True,
        capture_output=True,
    )


@pytest.fixture(scope="session")
def served_lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServedLab]:
    """One lab for this worker's client tests."""
    with serve_lab(tmp_path_factory) as served:
        yield served


@contextlib.contextmanager
def serve_lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServedLab]:
    """Start a lab (users tina, an administrator, and students ana, ben, carl); stop it after."""
    data_dir = tmp_path_factory.mktemp("client-lab")
    config = data_dir / "lab.toml"
    config.write_text(LAB_TOML, encoding="utf-8")
    _thermolab(
        data_dir,
        "user",
        "add",
        "tina",
        "--role",
        "admin",
        "--password-stdin",
        stdin=PASSWORD + "\n",
    )
    port = free_port()
    log = (data_dir / "server.log").open("wb")  # a file: a pipe nobody reads would fill up
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "thermolab",
            "--data-dir",
            str(data_dir),
            "serve",
            "--port",
            str(port),
            "--config",
            str(config),
            "--speedup",
            str(SPEEDUP),
            "--log-format",
            "json",
        ],
        stdout=log,
        stderr=subprocess.STDOUT,
        # These tests start runs: the lab warms its methods up as a lab does (the
        # suite's other servers skip it, tests/conftest.py).
        env={**os.environ, "THERMOLAB_WARM_UP": "1"},
    )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                if httpx.get(f"{url}/api/version", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if process.poll() is not None or time.monotonic() > deadline:
                log.flush()
                text = (data_dir / "server.log").read_text(errors="replace")
                pytest.fail(f"the lab did not start: {text}")
            time.sleep(0.2)
        served = ServedLab(url, data_dir)
        with contextlib.closing(served.cookie_client("tina")) as teacher:
            for name in ("ana", "ben", "carl"):
                body = {"username": name, "password": PASSWORD, "role": "student"}
                assert teacher.post("/api/users", json=body).status_code == 201
        yield served
    finally:
        process.terminate()
        try:
            process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        log.close()
