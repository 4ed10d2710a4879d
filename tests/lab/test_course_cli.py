"""``thermolab course``: create, import a class list, one-line errors on a bad file, assistants."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest

from thermolab.lab.accounts.users import UserService
from thermolab.lab.audit.log import AuditLog
from thermolab.lab.clock import SystemClock
from thermolab.lab.db import Database

from .conftest import FAST_HASHER, PASSWORD
from .test_cli import run


@pytest.fixture(autouse=True)
def _cheap_hashes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(
        "thermolab.lab.accounts.security.default_password_hasher", lambda: FAST_HASHER
    )


def test_a_class_list_imported_twice_from_the_shell(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    data_dir = tmp_path / "data"
    base = ["--data-dir", str(data_dir)]
    status, _, err = run(
        [*base, "user", "add", "tina", "--role", "teacher", "--password-stdin"],
        capsys,
        monkeypatch,
        PASSWORD + "\n",
    )
    assert status == 0, err
    status, out, err = run(
        [*base, "course", "create", "ctrl1", "--title", "Controle I", "--teacher", "tina"],
        capsys,
        monkeypatch,
    )
    assert status == 0, err
    assert out.startswith("created course 'ctrl1' (Controle I); enrolment code ")
    roster = tmp_path / "turma.csv"
    roster.write_text("username;name\nJoão;João Gonçalves\nbia;Bia\n", encoding="utf-8")
    status, out, err = run([*base, "course", "import", "ctrl1", str(roster)], capsys, monkeypatch)
    assert status == 0, err
    assert "ctrl1: 2 created, 0 updated, 0 unchanged" in err
    passwords = dict(list(csv.reader(io.StringIO(out)))[1:])
    users = UserService(
        Database(f"sqlite:///{data_dir / 'thermolab.sqlite3'}"), SystemClock(), FAST_HASHER
    )
    joao = users.verify("joao", passwords["joao"])
    assert (joao.display_name, joao.must_change_password) == ("João Gonçalves", True)

    roster.write_text("username;name\nJOAO;João G.\nbia;Bia\n", encoding="utf-8")
    status, out, err = run([*base, "course", "import", "ctrl1", str(roster)], capsys, monkeypatch)
    assert (status, out) == (0, "")
    assert "ctrl1: 0 created, 1 updated, 1 unchanged" in err
    assert [u.username for u in users.list()] == ["bia", "joao", "tina"]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"username,display_name\nana,Ana\nJo\x81o,Jo\x81o\n", "line 3: the file is not text"),
        (b"user,display\nana,Ana\n", "line 1: the header has columns"),
        (b"username,display_name\nana,Ana\nAna,Ana\n", "line 3: login name 'ana' is already"),
    ],
)
def test_a_bad_class_list_is_one_line_and_changes_nothing(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    content: bytes,
    message: str,
) -> None:
    base = ["--data-dir", str(tmp_path / "data")]
    run(
        [*base, "user", "add", "tina", "--role", "teacher", "--password-stdin"],
        capsys,
        monkeypatch,
        PASSWORD + "\n",
    )
    run([*base, "course", "create", "c1", "--title", "C", "--teacher", "tina"], capsys, monkeypatch)
    roster = tmp_path / "bad.csv"
    roster.write_bytes(content)
    status, out, err = run([*base, "course", "import", "c1", str(roster)], capsys, monkeypatch)
    assert (status, out) == (1, "")
    assert len(err.strip().splitlines()) == 1, err
    assert message in err
    assert "nothing changed" in err
    assert "Traceback" not in err
    status, _, err = run(
        [*base, "course", "import", "c1", str(tmp_path / "missing.csv")], capsys, monkeypatch
    )
    assert status == 1
    assert err.startswith("error: cannot read")
    status, _, err = run(
        [*base, "course", "create", "c2", "--title", "C", "--teacher", "nobody"],
        capsys,
        monkeypatch,
    )
    assert status == 1
    assert err.strip() == "error: no user called 'nobody'"


def test_an_assistant_is_added_and_removed_from_the_shell(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    base = ["--data-dir", str(tmp_path / "data")]
    for name, role in (("tina", "teacher"), ("rafa", "student")):
        command = [*base, "user", "add", name, "--role", role, "--password-stdin"]
        assert run(command, capsys, monkeypatch, PASSWORD + "\n")[0] == 0
    create = [*base, "course", "create", "ctrl1", "--title", "C", "--teacher", "tina"]
    assert run(create, capsys, monkeypatch)[0] == 0
    status, out, err = run([*base, "course", "assistant", "ctrl1", "Rafa"], capsys, monkeypatch)
    assert (status, out) == (0, "rafa assists course 'ctrl1'\n"), err
    # A teacher of the course is not made its assistant: one line, exit 1.
    status, out, err = run([*base, "course", "assistant", "ctrl1", "tina"], capsys, monkeypatch)
    assert status == 1
    assert len(err.strip().splitlines()) == 1
    assert "tina is a teacher of course 'ctrl1'" in err
    remove = [*base, "course", "assistant", "ctrl1", "rafa", "--remove"]
    assert run(remove, capsys, monkeypatch)[:2] == (0, "rafa no longer assists course 'ctrl1'\n")
    status, _, err = run(remove, capsys, monkeypatch)
    assert status == 1
    assert "rafa does not assist course 'ctrl1'" in err
    db = Database(f"sqlite:///{tmp_path / 'data' / 'thermolab.sqlite3'}")
    try:
        logged = [(r.action, r.target) for r in AuditLog(db, SystemClock()).list()]
    finally:
        db.close()
    assert logged[:2] == [
        ("course.assistant_removed", "ctrl1"),
        ("course.assistant_added", "ctrl1"),
    ]
