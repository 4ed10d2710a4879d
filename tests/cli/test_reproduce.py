"""``thermolab reproduce table1`` end to end: the table, JSON, figures and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from thermolab.cli import main

Run = Callable[..., tuple[int, str, str]]


@pytest.fixture
def run(capsys: pytest.CaptureFixture[str]) -> Run:
    def call(*argv: str) -> tuple[int, str, str]:
        status = main(["reproduce", *argv])
        out, err = capsys.readouterr()
        return status, out, err

    return call


def _line(text: str, start: str) -> str:
    return next(line for line in text.splitlines() if line.startswith(start))


def test_table_prints_ours_beside_the_papers_figures(run: Run) -> None:
    status, out, err = run("table1", "--runs", "SRM,LSM(1),LSM(2)")
    assert status == 0, err
    srm = _line(out, "SRM")
    # ours, the paper's, the deviation, and the mark for matching printed digits
    assert srm.split()[3:] == ["0.140042", "0.140042", "+0.000000", "="]
    assert "250.120736" in out  # the paper's LSM(2) minimum, beside ours
    assert "variant: exact simulation" in out
    assert "match to the printed digits: SRM, LSM(1);" in out
    assert err == ""


def test_json_has_the_documented_shape(run: Run) -> None:
    status, out, _ = run("table1", "--json", "--runs", "MALSM,WLSM(2)")
    assert status == 0
    d = json.loads(out)
    assert [r["run"] for r in d["rows"]] == ["MALSM", "WLSM(2)"]
    malsm, wlsm = d["rows"]
    for row in d["rows"]:
        for side in (row, row["paper"]):
            assert set(side["K"]) == {"mean", "max", "min"}
            assert set(side["tau"]) == {"mean", "max", "min"}
    assert malsm["converged_at"] is None
    assert malsm["paper"]["converged_at"] is None
    assert round(malsm["tau"]["min"], 6) == malsm["paper"]["tau"]["min"] == 250.126233
    assert set(wlsm["converged_at"]) == {"K", "tau"}
    assert wlsm["paper"]["converged_at"] == {"K": 29, "tau": 37}
    assert wlsm["agreement"]["convergence_order"] is True


def test_variant_options_reach_the_machinery(run: Run) -> None:
    status, out, _ = run("table1", "--json", "--runs", "LSM(2)", "--paper-arithmetic")
    assert status == 0
    d = json.loads(out)
    assert d["options"]["solver"] == "explicit-inverse"
    assert d["options"]["covariance"] == "frozen"
    tau_min = d["rows"][0]["tau"]["min"]
    assert 1e-4 < 250.126233 - tau_min < 5e-2
    status, out, _ = run(
        "table1", "--json", "--runs", "SRM", "--quantum", "daq16", "--noise", "0", "--seed", "3"
    )
    assert status == 0
    opts = json.loads(out)["options"]
    assert opts["quantum"] == pytest.approx(20 / 65536, rel=1e-15)
    assert opts["seed"] == 3


def test_plot_writes_one_figure_per_row(run: Run, tmp_path: Path) -> None:
    out_dir = tmp_path / "figs"
    status, out, err = run("table1", "--runs", "SRM,LSM(2),WLSM(2)", "--plot", str(out_dir))
    assert status == 0, err
    files = sorted(p.name for p in out_dir.iterdir())
    assert files == ["table1-lsm2.png", "table1-srm.png", "table1-wlsm2.png"]
    for name in files:
        assert (out_dir / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"wrote 3 figures to {out_dir}" in out


def test_plot_with_json_keeps_stdout_pure_json(run: Run, tmp_path: Path) -> None:
    status, out, err = run("table1", "--json", "--runs", "LSM(3)", "--plot", str(tmp_path))
    assert status == 0
    json.loads(out)
    assert "wrote 1 figure to" in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["table2"], "invalid choice: 'table2'"),
        (["table1", "--runs", "LSM(9)"], "unknown run 'LSM(9)'"),
        (["table1", "--noise", "-1"], "--noise must be >= 0"),
        (["table1", "--noise", "lots"], "--noise must be a number"),
        (["table1", "--quantum", "0"], "--quantum must be > 0 volts or daq16"),
        (["table1", "--decimals", "20"], "--decimals must be between 0 and 15"),
        (["table1", "--solver", "qr"], "invalid choice: 'qr'"),
        (["table1", "--paper-arithmetic", "--covariance", "propagated"], "contradicts"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(run: Run, argv: list[str], message: str) -> None:
    status, out, err = run(*argv)
    assert status == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1
    assert message in err
    assert "Traceback" not in err


def test_unwritable_plot_directory_is_one_line(run: Run, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    status, _, err = run("table1", "--runs", "LSM(2)", "--plot", str(blocker / "figs"))
    assert status == 1
    assert len(err.strip().splitlines()) == 1
    assert err.startswith(f"error: --plot {blocker / 'figs'}: cannot write")


def test_console_command_runs_as_a_subprocess() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "thermolab", "reproduce", "table1", "--json", "--runs", "LSM(1)"],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    row = json.loads(proc.stdout)["rows"][0]
    assert row["run"] == "LSM(1)"
    assert round(row["K"]["mean"], 6) == row["paper"]["K"]["mean"] == 0.14009
