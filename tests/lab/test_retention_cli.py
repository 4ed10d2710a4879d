"""``thermolab retention apply [--dry-run]``: the retention period from the shell."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text

from thermolab.lab.config import default_database_url

from .conftest import FAST_HASHER, PASSWORD
from .test_cli import run


@pytest.fixture(autouse=True)
def _cheap_hashes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(
        "thermolab.lab.accounts.security.default_password_hasher", lambda: FAST_HASHER
    )


def test_the_period_from_the_file_the_environment_or_the_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    data = tmp_path / "data"
    base = ["--data-dir", str(data)]

    def shell(*words: str, stdin: str = "") -> tuple[int, str, str]:
        return run([*base, *words], capsys, monkeypatch, stdin)

    monkeypatch.setenv("LANG", "C")
    monkeypatch.delenv("THERMOLAB_RETENTION_MONTHS", raising=False)
    monkeypatch.delenv("THERMOLAB_RETENTION_ACTION", raising=False)
    add = ("user", "add", "tina", "--role", "teacher", "--password-stdin")
    assert shell(*add, stdin=PASSWORD)[0] == 0
    assert shell("course", "create", "ctrl1", "--title", "Controle I", "--teacher", "tina")[0] == 0
    roster = tmp_path / "turma.csv"
    roster.write_text("username,display_name\nana,Ana Lima\nbeto,Beto Souza\n", encoding="utf-8")
    assert shell("course", "import", "ctrl1", str(roster))[0] == 0
    assert shell("course", "close", "ctrl1", "--by", "tina")[0] == 0

    # Unset: nothing is ever removed, and the command says how to set it.
    status, out, err = shell("retention", "apply")
    assert (status, out) == (1, "")
    assert err.startswith("error: no retention period is set, so nobody is removed automatically")
    # Closed just now: nobody is past a year.
    status, out, err = shell("retention", "apply", "--retention-months", "12")
    assert status == 0, err
    assert out.startswith("removed 0 students whose courses all closed before ")

    # The course closed two years ago (as if the time had passed).
    engine = create_engine(default_database_url(data))
    with engine.begin() as connection:
        long_ago = datetime(2020, 3, 1, tzinfo=UTC).replace(tzinfo=None)
        connection.execute(text("UPDATE courses SET closed_at = :t"), {"t": long_ago})
    engine.dispose()
    status, out, err = shell("retention", "apply", "--retention-months", "12", "--dry-run")
    assert status == 0, err
    assert out.splitlines() == ["ana\t2020-03-01", "beto\t2020-03-01"]
    assert "without --dry-run they are removed (pseudonymise)" in err
    status, out, _ = shell("user", "list")
    assert "ana" in out  # the dry run changed nothing

    # From the configuration file, the environment over it, the option over both.
    config = tmp_path / "lab.toml"
    config.write_text('[retention]\nmonths = 600\naction = "delete"\n', encoding="utf-8")
    status, out, err = shell("retention", "apply", "--config", str(config))
    assert (status, out.split(" whose")[0]) == (0, "removed 0 students")
    monkeypatch.setenv("THERMOLAB_RETENTION_MONTHS", "24")
    status, out, err = shell("retention", "apply", "--config", str(config), "--dry-run")
    assert (status, len(out.splitlines())) == (0, 2)
    assert "removed (delete)" in err
    status, out, err = shell(
        "retention", "apply", "--config", str(config), "--retention-action", "pseudonymise"
    )
    assert status == 0, err
    assert out.startswith("removed 2 students whose courses all closed before ")
    assert "(pseudonymise)" in out
    status, out, _ = shell("user", "list")
    names = {line.split()[0] for line in out.splitlines() if line.strip()}
    assert "tina" in names
    assert not {"ana", "beto"} & names
    status, out, _ = shell("retention", "apply", "--dry-run")
    assert (status, out) == (0, "")

    # Bad values: one line, non-zero.
    status, _, err = shell("retention", "apply", "--retention-months", "0")
    assert status == 2
    assert "expected a whole number of months from 1 to 1200, got '0'" in err
    monkeypatch.setenv("THERMOLAB_RETENTION_MONTHS", "soon")
    status, _, err = shell("retention", "apply")
    assert (status, err.count("\n")) == (1, 1)
    assert "THERMOLAB_RETENTION_MONTHS: expected a whole number of months, got 'soon'" in err
    assert "Traceback" not in err
