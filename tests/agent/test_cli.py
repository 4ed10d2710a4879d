"""``thermolab agent`` and ``thermolab agent-secret``: bad input is one line and a non-zero exit."""

from __future__ import annotations

from pathlib import Path

import pytest

from thermolab.cli import main
from thermolab.lab.agents import check_secret
from thermolab.lab.db import Database

TOML = """
[[rigs]]
id = "far"
spec = "sim:tclab"
agent = true

[[rigs]]
id = "near"
spec = "sim"
"""


def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = main(args)
    out, err = capsys.readouterr()
    return status, out, err


def test_agent_secret_issues_rotates_and_refuses_a_local_rig(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "lab.toml"
    config.write_text(TOML)
    base = ["--data-dir", str(tmp_path), "agent-secret"]
    status, _, err = _run([*base, "far", "--config", str(config)], capsys)
    assert status == 1  # the lab never started: no rig rows yet
    assert "start the lab once" in err
    assert len(err.strip().splitlines()) == 1
    from thermolab.lab.config import load_config
    from thermolab.lab.service import Lab

    lab = Lab(load_config(config, tmp_path))
    lab.start()
    lab.close()
    status, first, _ = _run([*base, "far", "--config", str(config)], capsys)
    assert status == 0
    status, second, _ = _run([*base, "far", "--config", str(config)], capsys)
    assert status == 0
    assert first.strip() != second.strip()
    db = Database(f"sqlite:///{tmp_path / 'thermolab.sqlite3'}")
    try:
        assert check_secret(db, "far", second.strip())
        assert not check_secret(db, "far", first.strip())  # rotated
    finally:
        db.close()
    status, _, err = _run([*base, "near", "--config", str(config)], capsys)
    assert status == 1
    assert "not a remote rig" in err
    status, _, err = _run([*base, "nowhere", "--config", str(config)], capsys)
    assert status == 1
    assert "no rig called 'nowhere'" in err


@pytest.mark.parametrize(
    ("args", "says", "code"),
    [
        (["--lab", "http://lab"], "use wss://HOST:PORT", 2),
        (["--lab", "wss://lab", "--spec", "warp:9"], "warp", 1),
        (["--lab", "wss://lab", "--secret-file", "/nonexistent/secret"], "cannot read", 1),
    ],
)
def test_agent_refuses_bad_options_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], says: str, code: int
) -> None:
    secret = tmp_path / "s"
    secret.write_text("x" * 43)
    base = {
        "--lab": "wss://lab",
        "--rig": "far",
        "--spec": "sim:tclab",
        "--secret-file": str(secret),
    }
    for i in range(0, len(args), 2):
        base[args[i]] = args[i + 1]
    argv = ["agent", *[x for pair in base.items() for x in pair]]
    status, _, err = _run(argv, capsys)
    assert status == code
    assert says in err
    assert len(err.strip().splitlines()) == 1
