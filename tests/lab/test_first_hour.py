"""A teacher's first hour (issue #24, item 1), as the README leaves them.

``.venv/bin/thermolab serve`` with no option, no file and the venv not
activated; the commands the first start prints are run as printed (their
placeholders filled) in a second terminal that opens in another folder, the
password typed at the prompt; then a student runs the paper's first
experiment (a step from 0 to 10 V, 2000 samples at T = 1 s) over HTTP, and it
ends within a minute of wall time, with no setting made.

A real ``serve`` process, real commands in a pseudo-terminal, nothing mocked;
the per-user data folder is a temporary one (``XDG_DATA_HOME``).
"""

from __future__ import annotations

import contextlib
import csv
import os
import re
import select
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

pytestmark = pytest.mark.slow

PASSWORD = "a long enough password"
#: Placeholders of the first start's commands, as the teacher fills them in.
FILLED = {"COURSE": "ctrl1", "TITLE": shlex.quote("Controle I")}
#: The prompts of ``thermolab user add`` on a terminal.
PROMPT = re.compile(rb"(?:Password for [^\r\n]*|Repeat the password): ")
#: The message's last line: everything before it has been printed.
LAST_LINE = "(a teacher can also do this on a course's page once logged in.)"


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def _quick_start_program(home: Path) -> Path:
    """``home/.venv/bin/thermolab``: this venv's ``thermolab`` script (its shebang names this
    venv's python), where the README's quick start puts it."""
    script = Path(sys.executable).parent / "thermolab"
    if not script.is_file() or not script.read_bytes().startswith(b"#!"):
        pytest.skip(f"no thermolab console script beside {sys.executable}")
    program = home / ".venv" / "bin" / "thermolab"
    program.parent.mkdir(parents=True)
    shutil.copy2(script, program)
    return program


def _in_a_terminal(line: str, cwd: Path, env: dict[str, str], timeout: float = 120) -> str:
    """Run a shell line as a person would in a terminal (a pseudo-terminal: the password is
    asked and typed); return what it printed. Fails unless it exits 0."""
    leader, follower = os.openpty()
    process = subprocess.Popen(
        ["bash", "-c", line],
        cwd=cwd,
        env=env,
        stdin=follower,
        stdout=follower,
        stderr=follower,
        start_new_session=True,  # no controlling terminal but this one: getpass reads it
    )
    os.close(follower)
    output, answered = b"", 0
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([leader], [], [], 0.2)
            if ready:
                try:
                    chunk = os.read(leader, 4096)
                except OSError:  # EIO: the command closed the terminal
                    chunk = b""
                if not chunk:
                    break
                output += chunk
                while len(PROMPT.findall(output)) > answered:
                    os.write(leader, (PASSWORD + "\n").encode())
                    answered += 1
        status = process.wait(timeout=max(1.0, deadline - time.monotonic()))
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        os.close(leader)
    text = output.decode(errors="replace")
    assert status == 0, f"{line!r} failed ({status}): {text}"
    return text


@contextlib.contextmanager
def _quick_start(tmp_path: Path) -> Iterator[tuple[str, str, dict[str, str]]]:
    """``.venv/bin/thermolab serve`` as the README runs it: (URL, its first words, env)."""
    home = tmp_path / "teacher"
    _quick_start_program(home)
    venv_bin = str(Path(sys.executable).parent)
    path = [p for p in os.environ.get("PATH", "").split(os.pathsep) if p and p != venv_bin]
    env = {**os.environ, "PATH": os.pathsep.join(path), "XDG_DATA_HOME": str(tmp_path / "xdg")}
    env.pop("THERMOLAB_DATA_DIR", None)
    env.pop("VIRTUAL_ENV", None)
    assert shutil.which("thermolab", path=env["PATH"]) is None, "thermolab must not be on PATH"
    port = _free_port()
    log_path = tmp_path / "serve.log"
    with log_path.open("wb") as log:  # a file: a pipe nobody reads would fill up
        server = subprocess.Popen(
            [".venv/bin/thermolab", "serve", "--port", str(port)],
            cwd=home,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        url = f"http://127.0.0.1:{port}"
        try:
            deadline = time.monotonic() + 90
            while LAST_LINE not in (said := log_path.read_text(errors="replace")):
                if server.poll() is not None or time.monotonic() > deadline:
                    pytest.fail(f"the lab did not start: {said}")
                time.sleep(0.2)
            while True:
                with contextlib.suppress(httpx.HTTPError):
                    if httpx.get(f"{url}/api/version", timeout=2).status_code == 200:
                        break
                if server.poll() is not None or time.monotonic() > deadline:
                    pytest.fail(f"the lab does not answer: {log_path.read_text()}")
                time.sleep(0.2)
            yield url, said, env
        finally:
            server.send_signal(signal.SIGTERM)
            try:
                server.wait(timeout=20)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()


def test_the_quick_start_runs_the_papers_first_experiment_within_a_minute(
    tmp_path: Path,
) -> None:
    with _quick_start(tmp_path) as (url, said, env):
        program = str(tmp_path / "teacher" / ".venv" / "bin" / "thermolab")
        commands = [line.strip() for line in said.splitlines() if line.startswith("    ")]
        # The running program by its absolute path (the venv is not activated, and this is
        # typed in another terminal), the per-user data folder left implicit.
        assert commands == [
            f"{program} user add NAME --role admin",
            f"{program} user add NAME --role teacher",
            f"{program} course create COURSE --title TITLE --teacher NAME",
            f"{program} course import COURSE class.csv > passwords.csv",
            f"{program} user add NAME --role student",
        ], said
        assert "twin speed-ups: twin 60x" in said
        # A second terminal, in another folder (where the class list is).
        elsewhere = tmp_path / "elsewhere"
        elsewhere.mkdir()
        (elsewhere / "class.csv").write_text("username,display_name\nana,Ana Souza\n")
        names = iter(["root", "tina", "tina", None, "bia"])
        for command in commands:
            name = next(names)
            line = command.replace("NAME", name) if name else command
            for placeholder, value in FILLED.items():
                line = line.replace(placeholder, value)
            _in_a_terminal(line, elsewhere, env)
        with (elsewhere / "passwords.csv").open(newline="") as handed_out:
            assert [row["username"] for row in csv.DictReader(handed_out)] == ["ana"]

        with httpx.Client(base_url=url, timeout=10) as bia:
            login = bia.post("/api/session", json={"username": "bia", "password": PASSWORD})
            assert login.status_code == 200, login.text
            assert bia.post("/api/rigs/twin/control").status_code == 200
            rig = bia.get("/api/rigs/twin").json()
            assert (rig["speedup"], rig["limits"]["controlTimeLimit"]) == (60.0, 300.0)
            began = time.monotonic()
            body = {"dt": 1.0, "samples": 2000, "signal": "step:0:10@1"}
            started = bia.post("/api/rigs/twin/runs", json=body)
            assert started.status_code == 201, started.text
            run_id = started.json()["id"]
            while (run := bia.get(f"/api/runs/{run_id}").json())["status"] == "running":
                assert time.monotonic() - began < 90, run
                bia.post("/api/rigs/twin/heartbeat")
                time.sleep(0.5)
            took = time.monotonic() - began
        assert (run["status"], run["samplesTaken"]) == ("finished", 2000), run
        assert took < 60.0, f"the paper's first experiment took {took:.1f} s"
        # The step method's gain, as the paper found it on the reference model.
        assert run["results"]["srm"]["latest"]["K"] == pytest.approx(0.14009, abs=1e-4)
