"""``thermolab course close|reopen|copy|purge-students``: the end of a term from the shell."""

from __future__ import annotations

from pathlib import Path

import pytest

from .conftest import FAST_HASHER, PASSWORD
from .test_cli import run


@pytest.fixture(autouse=True)
def _cheap_hashes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(
        "thermolab.lab.accounts.security.default_password_hasher", lambda: FAST_HASHER
    )


def test_a_term_closed_copied_and_its_students_removed_from_the_shell(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    base = ["--data-dir", str(tmp_path / "data")]

    def shell(*words: str, stdin: str = "") -> tuple[int, str, str]:
        return run([*base, *words], capsys, monkeypatch, stdin)

    monkeypatch.setenv("LANG", "C")
    assert (
        shell("user", "add", "tina", "--role", "teacher", "--password-stdin", stdin=PASSWORD)[0]
        == 0
    )
    assert shell("course", "create", "ctrl1", "--title", "Controle I", "--teacher", "tina")[0] == 0
    roster = tmp_path / "turma.csv"
    roster.write_text("matrícula;nome\nana;Ana Lima\nbeto;Beto Souza\n", encoding="utf-8")
    assert shell("course", "import", "ctrl1", str(roster))[0] == 0

    # Not while the course is open: one line, exit 1.
    status, out, err = shell("course", "purge-students", "ctrl1")
    assert (status, out) == (1, "")
    assert err.strip() == "error: course 'ctrl1' is open: close it before removing its students"

    status, out, err = shell("course", "close", "ctrl1", "--by", "tina")
    assert status == 0, err
    assert out.strip() == (
        "closed course 'ctrl1': it can be read and exported, not changed; "
        "0 bookings that had not begun were cancelled, freeing their rigs"
    )
    status, _, err = shell("course", "import", "ctrl1", str(roster))
    assert status == 1
    assert err.startswith("error: course 'ctrl1' was closed on ")
    assert len(err.strip().splitlines()) == 1

    status, out, err = shell("course", "copy", "ctrl1", "ctrl1-b", "--shift-days", "182")
    assert status == 0, err
    assert out.startswith("copied 'ctrl1' to 'ctrl1-b' (teacher tina, dates moved 182 days)")
    status, _, err = shell("course", "copy", "ctrl1", "ctrl1-b", "--shift-days", "182")
    assert (status, err.strip()) == (
        1,
        "error: course 'ctrl1-b' already exists; choose another name",
    )
    status, _, err = shell("course", "copy", "nope", "x", "--shift-days", "7")
    assert (status, err.strip()) == (1, "error: no course called 'nope'")
    status, _, err = shell("course", "copy", "ctrl1", "x", "--shift-days", "9000")
    assert status == 1
    assert err.strip() == "error: a copy moves its dates by at most 800 days, not 9000"
    status, _, err = shell("course", "copy", "ctrl1", "x", "--starts", "31/08/2026")
    assert status == 2
    assert "'31/08/2026' is not a day written YYYY-MM-DD" in err
    assert "Traceback" not in err

    # The dry run lists them and changes nothing; --yes removes them.
    status, out, err = shell("course", "purge-students", "ctrl1")
    assert status == 0, err
    assert out.splitlines() == ["ana\tAna Lima", "beto\tBeto Souza"]
    assert "add --yes" in err
    status, out, err = shell("course", "purge-students", "ctrl1", "--yes")
    assert status == 0, err
    assert out.strip() == "removed 2 students of 'ctrl1' (runs keep)"
    status, out, err = shell("course", "purge-students", "ctrl1")
    assert (status, out) == (0, "")
    status, out, err = shell("course", "reopen", "ctrl1")
    assert (status, out.strip()) == (0, "reopened course 'ctrl1'")
