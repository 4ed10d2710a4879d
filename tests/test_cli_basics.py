"""The command line's framing: help, version, one-line errors."""

from __future__ import annotations

import subprocess
import sys

import pytest

from thermolab import __version__
from thermolab.cli import main


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert __version__ in capsys.readouterr().out


def test_unknown_subcommand_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["no-such-command"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "invalid choice" in err


def test_console_entry_point_runs() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "thermolab", "--help"], capture_output=True, text=True, check=False
    )
    assert out.returncode == 0
    assert "thermolab" in out.stdout
