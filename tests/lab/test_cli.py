"""``thermolab user`` and ``thermolab serve``: accounts from the shell, one-line errors."""

from __future__ import annotations

import io
import socket
import sys
from pathlib import Path
from typing import Any

import pytest

import thermolab.cli.serve
from thermolab.cli import main
from thermolab.lab.accounts.users import UserService
from thermolab.lab.clock import SystemClock
from thermolab.lab.db import Database

from .conftest import FAST_HASHER, PASSWORD


def run(
    args: list[str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    stdin: str = "",
) -> tuple[int, str, str]:
    monkeypatch.setattr("sys.stdin", io.StringIO(stdin))
    status = main(args)
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture(autouse=True)
def _cheap_hashes(monkeypatch: pytest.MonkeyPatch) -> None:
    """Argon2 at its cheapest: the commands hash a password each (production: the defaults)."""
    monkeypatch.setattr(
        "thermolab.lab.accounts.security.default_password_hasher", lambda: FAST_HASHER
    )


@pytest.fixture
def data_dir(tmp_path: Path) -> Path:
    return tmp_path / "data"


def users_of(data_dir: Path) -> UserService:
    return UserService(
        Database(f"sqlite:///{data_dir / 'thermolab.sqlite3'}"), SystemClock(), FAST_HASHER
    )


def test_add_list_passwd_remove(
    data_dir: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    base = ["--data-dir", str(data_dir), "user"]
    status, out, _ = run([*base, "list"], capsys, monkeypatch)
    assert (status, out.strip()) == (
        0,
        "no accounts yet; add the lab's administrator with: "
        f"thermolab --data-dir {data_dir.resolve()} user add NAME --role admin",
    )
    status, out, err = run(
        [*base, "add", "Tina", "--role", "teacher", "--password-stdin"],
        capsys,
        monkeypatch,
        stdin=PASSWORD + "\n",
    )
    assert (status, out.strip(), err) == (0, "added teacher 'tina'", "")
    run(
        [*base, "add", "ana", "--role", "student", "--password-stdin"],
        capsys,
        monkeypatch,
        "pw-ana-123-xyz\n",
    )
    status, out, _ = run([*base, "list"], capsys, monkeypatch)
    lines = out.splitlines()
    assert lines[0].split() == ["username", "role", "created", "(UTC)"]
    assert [line.split()[:2] for line in lines[1:]] == [["ana", "student"], ["tina", "teacher"]]
    users = users_of(data_dir)
    assert users.verify("tina", PASSWORD).username == "tina"
    status, out, _ = run(
        [*base, "passwd", "ana", "--password-stdin"], capsys, monkeypatch, "a new passphrase\n"
    )
    assert (status, out.strip()) == (0, "changed the password of 'ana'; their logins have ended")
    assert users.verify("ana", "a new passphrase").username == "ana"
    status, out, _ = run([*base, "remove", "ana"], capsys, monkeypatch)
    assert (status, out.strip()) == (0, "removed student 'ana'")
    assert [u.username for u in users.list()] == ["tina"]


@pytest.mark.parametrize(
    ("args", "stdin", "status", "message"),
    [
        (
            ["add", "tina", "--role", "teacher", "--password-stdin"],
            PASSWORD + "\n",
            1,
            "error: user 'tina' already exists",
        ),
        (
            ["add", "bob", "--role", "boss", "--password-stdin"],
            PASSWORD + "\n",
            1,
            "error: role 'boss' is not known; use 'student', 'teacher' or 'admin'",
        ),
        (
            ["add", "bo b", "--role", "student", "--password-stdin"],
            PASSWORD + "\n",
            1,
            "error: user name 'bo b' is not valid",
        ),
        (
            ["add", "bob", "--role", "student", "--password-stdin"],
            "short\n",
            1,
            "error: password too short: at least 12 characters are needed",
        ),
        (
            ["add", "bob", "--role", "student", "--password-stdin"],
            "password1234\n",
            1,
            "error: this password is in a list of breached passwords; choose another",
        ),
        (
            ["add", "bob.smith", "--role", "student", "--password-stdin"],
            "Bob.Smith-2024\n",
            1,
            "error: the password may not be the user name or a variant of it",
        ),
        (
            ["add", "bob", "--role", "student", "--password-stdin"],
            "",
            1,
            "error: no password on standard input",
        ),
        (["add", "bob", "--role", "student"], "", 1, "error: standard input is not a terminal"),
        (["add", "bob"], "", 2, "the following arguments are required: --role"),
        (
            ["passwd", "nobody", "--password-stdin"],
            PASSWORD + "\n",
            1,
            "error: no user called 'nobody'",
        ),
        (["remove", "nobody"], "", 1, "error: no user called 'nobody'"),
        ([], "", 2, "the following arguments are required: ACTION"),
        (
            ["list", "--database-url", "mysql://u@h/db"],
            "",
            1,
            "error: database 'mysql' is not supported",
        ),
        (
            ["list", "--database-url", "postgresql://nobody@127.0.0.1:1/x"],
            "",
            1,
            "error: cannot open the database postgresql+psycopg://nobody@127.0.0.1:1/x",
        ),
        (
            ["list", "--config", "missing.toml"],
            "",
            1,
            "error: missing.toml: no such configuration file",
        ),
    ],
)
def test_errors_are_one_line(
    data_dir: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    args: list[str],
    stdin: str,
    status: int,
    message: str,
) -> None:
    base = ["--data-dir", str(data_dir), "user"]
    run(
        [*base, "add", "tina", "--role", "teacher", "--password-stdin"],
        capsys,
        monkeypatch,
        PASSWORD + "\n",
    )
    got, _out, err = run(base + args, capsys, monkeypatch, stdin)
    assert got == status
    assert len(err.strip().splitlines()) == 1, err
    assert message in err
    assert "Traceback" not in err


def test_passwords_asked_on_a_terminal_twice(
    data_dir: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    answers = iter(["first password", "other password", PASSWORD, PASSWORD])
    monkeypatch.setattr("getpass.getpass", lambda prompt="": next(answers))
    tty = io.StringIO()
    tty.isatty = lambda: True  # type: ignore[method-assign]
    monkeypatch.setattr("sys.stdin", tty)
    base = ["--data-dir", str(data_dir), "user", "add", "ana", "--role", "student"]
    assert main(base) == 1
    assert capsys.readouterr().err.strip() == "error: the two passwords differ; nothing was changed"
    assert main(base) == 0
    assert users_of(data_dir).verify("ana", PASSWORD).username == "ana"


@pytest.mark.postgres
def test_user_commands_on_postgresql(
    postgres_url: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    args = ["user", "add", "tina", "--role", "teacher", "--password-stdin"]
    status, out, err = run(
        [*args, "--database-url", postgres_url], capsys, monkeypatch, PASSWORD + "\n"
    )
    assert (status, out.strip(), err) == (0, "added teacher 'tina'", "")
    status, out, _ = run(["user", "list", "--database-url", postgres_url], capsys, monkeypatch)
    assert "tina" in out


class _Served:
    def __init__(self) -> None:
        self.calls: list[tuple[Any, str, int]] = []

    def __call__(self, app: Any, host: str, port: int, **limits: Any) -> None:
        self.calls.append((app, host, port))


def test_serve_starts_a_lab_and_says_how_to_add_a_teacher(
    data_dir: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    served = _Served()
    monkeypatch.setattr(thermolab.cli.serve, "run_server", served)
    status, _, err = run(["--data-dir", str(data_dir), "serve", "--port", "0"], capsys, monkeypatch)
    assert (status, err.strip()) == (2, "error: --port 0 is not a TCP port (1-65535)")
    port = _free_port()
    status, _, err = run(
        ["--data-dir", str(data_dir), "serve", "--port", str(port)], capsys, monkeypatch
    )
    assert status == 0
    ((app, host, got_port),) = served.calls
    assert (host, got_port) == ("127.0.0.1", port)
    assert (data_dir / "thermolab.sqlite3").is_file()
    assert f"ThermoLab on http://127.0.0.1:{port}/" in err
    assert "rigs: twin (sim)" in err
    assert "No teacher account yet" in err
    assert f"thermolab --data-dir {data_dir} user add NAME --role admin" in err
    assert any(getattr(route, "name", "") == "web" for route in app.routes)  # the browser UI
    run(
        [
            "--data-dir",
            str(data_dir),
            "user",
            "add",
            "tina",
            "--role",
            "teacher",
            "--password-stdin",
        ],
        capsys,
        monkeypatch,
        PASSWORD + "\n",
    )
    status, _, err = run(
        ["--data-dir", str(data_dir), "serve", "--port", str(port)], capsys, monkeypatch
    )
    assert status == 0
    assert "No teacher account yet" not in err


def test_serve_refuses_a_busy_port_and_a_bad_config(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(thermolab.cli.serve, "run_server", _Served())
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        status, _, err = run(
            ["--data-dir", str(tmp_path), "serve", "--port", str(port)], capsys, monkeypatch
        )
    assert status == 1
    assert f"error: cannot listen on 127.0.0.1:{port}" in err
    config = tmp_path / "lab.toml"
    config.write_text("[[rigs]]\nid = 'a'\nspec = 'sim'\nidle_limit = 'x'\n")
    status, _, err = run(
        ["--data-dir", str(tmp_path), "serve", "--config", str(config)], capsys, monkeypatch
    )
    assert status == 1
    assert err.strip() == f"error: {config}: rigs[0].idle_limit: expected a number, got str 'x'"
    status, _, err = run(["serve", "--speedup", "-3"], capsys, monkeypatch)
    assert (status, err.strip()) == (1, "error: --speedup: expected a finite number > 0, got -3.0")
    # A standby takes the rigs over from an owner it hears on a broker: none, no standby.
    status, _, err = run(
        ["--data-dir", str(tmp_path), "serve", "--port", str(_free_port()), "--standby"],
        capsys,
        monkeypatch,
    )
    assert (status, err.strip()) == (
        2,
        "error: --standby: a standby follows an owner; give --broker too",
    )
    # The CA a follower trusts for the owner's https:// address: a file of certificates.
    not_a_ca = tmp_path / "ca.pem"
    not_a_ca.write_text("no certificate here\n")
    status, _, err = run(
        ["--data-dir", str(tmp_path), "serve", "--port", str(_free_port()), "--ca", str(not_a_ca)],
        capsys,
        monkeypatch,
    )
    assert status == 2
    assert err.strip().startswith(f"error: --ca {not_a_ca}: not a CA certificate file ("), err
    assert len(err.strip().splitlines()) == 1


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def test_the_first_start_hint_names_the_command_as_it_can_be_typed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The quick start runs ``.venv/bin/thermolab`` from a venv that is not activated; the
    hint is typed in a second terminal, in another folder: the program's absolute path."""
    from thermolab.cli.first_start import command_name

    script = tmp_path / "lab folder" / ".venv" / "bin" / "thermolab"
    script.parent.mkdir(parents=True)
    script.write_text("#!/bin/sh\n")
    script.chmod(0o755)
    monkeypatch.chdir(script.parent.parent.parent)
    monkeypatch.setattr("sys.argv", [".venv/bin/thermolab", "serve"])
    monkeypatch.setenv("PATH", "/usr/bin:/bin")
    assert command_name() == f"'{script}'"  # quoted: the folder's name has a space
    monkeypatch.setenv("PATH", str(script.parent))  # activated: the plain name works
    assert command_name() == "thermolab"
    import thermolab

    main_module = str(Path(thermolab.__file__).parent / "__main__.py")
    monkeypatch.setattr("sys.argv", [main_module])  # python -m thermolab
    monkeypatch.setenv("PATH", "/usr/bin:/bin")
    assert command_name() == f"{sys.executable} -m thermolab"
