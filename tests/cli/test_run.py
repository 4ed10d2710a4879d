"""``thermolab run`` end to end: table, JSON, CSV, faults, signals, usage errors."""

from __future__ import annotations

import csv
import io
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from numpy.testing import assert_allclose

import thermolab.rigs
from thermolab.cli import main
from thermolab.cli._run_report import Progress
from thermolab.rigs import Reading, Rig
from thermolab.rigs.tclab_emulator import TCLabEmulator
from thermolab.rigs.twin import TwinRig

FAST_STEP = ["run", "--rig", "sim", "--dt", "1", "--samples", "2000", "--fast"]


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture
def opened(monkeypatch: pytest.MonkeyPatch) -> Callable[..., list[Rig]]:
    """Wrap ``open_rig`` so a test can adjust the rig the CLI opens and inspect it after."""
    rigs: list[Rig] = []

    def install(adjust: Callable[[Rig], object] | None = None, **extra: Any) -> list[Rig]:
        real = thermolab.rigs.open_rig

        def wrapped(spec: str, **kwargs: Any) -> Rig:
            rig = real(spec, **kwargs, **extra)
            if adjust is not None:
                adjust(rig)
            rigs.append(rig)
            return rig

        monkeypatch.setattr(thermolab.rigs, "open_rig", wrapped)
        return rigs

    return install


def test_fast_run_prints_every_method_and_writes_the_csv(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.csv"
    status = main([*FAST_STEP, "--signal", "step:0:10@10", "--out", str(out)])
    captured = capsys.readouterr()
    assert status == 0
    assert captured.err == ""  # no progress bar when stderr is not a terminal
    lines = captured.out.splitlines()
    assert "samples: 2000/2000 (completed)" in lines[0]
    table = {line.split()[0]: line.split() for line in lines[4:]}
    assert list(table) == ["srm", "lsm", "blockls", "malsm", "wlsm", "oe"]
    assert table["lsm"][1:3] == ["0.140090", "250.126233"]
    assert table["srm"][1:3] == ["0.140090", "250.126233"]
    with out.open() as f:
        assert f.readline().startswith("t,u,y,")
    rows = _rows(out)
    assert len(rows) == 2000
    assert rows[10]["u"] == "10.0"
    assert rows[9]["u"] == "0.0"


def test_json_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.csv"
    status = main(
        [*FAST_STEP, "--signal", "square:0:4:0.1", "--method", "malsm,wlsm", "--window", "50",
         "--gamma", "0.7", "--json", "--out", str(out)]
    )  # fmt: skip
    assert status == 0
    report = json.loads(capsys.readouterr().out)
    assert report["end_reason"] == "completed"
    assert report["signal"] == "square:0:4:0.1"
    assert report["csv"] == str(out)
    assert report["interrupted_by"] is None
    assert set(report["methods"]) == {"malsm", "wlsm"}
    malsm = report["methods"]["malsm"]
    assert malsm["estimates"] == 2000 - 49
    assert_allclose(malsm["latest"]["K"], 0.140090, rtol=1e-9)
    assert_allclose(report["methods"]["wlsm"]["latest"]["tau"], 250.126233, rtol=1e-9)


def test_the_csv_feeds_straight_into_identify(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.csv"
    argv = "run --rig sim:paper-practical --seed 3 --dt 1 --samples 1500 --fast"
    argv += " --signal square:4:6:0.1 --method lsm --json --out"
    assert main([*argv.split(), str(out)]) == 0
    online = json.loads(capsys.readouterr().out)["methods"]["lsm"]["latest"]
    assert main(["identify", str(out), "--method", "lsm", "--json"]) == 0
    batch = json.loads(capsys.readouterr().out)
    # The CSV holds every float exactly, so the batch fit of the file is the online one.
    assert batch["W"] == online["W"]
    assert batch["K"] == online["K"]


def test_device_fault_keeps_the_csv_and_switches_off(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], opened: Callable[..., list[Rig]]
) -> None:
    def fail_at_30(rig: Rig) -> None:
        assert isinstance(rig, TwinRig)
        rig.inject_fault("lamp driver burnt out", at=rig.clock.now() + 30.0)

    rigs = opened(fail_at_30)
    out = tmp_path / "run.csv"
    status = main([*FAST_STEP, "--signal", "const:10", "--method", "srm,lsm", "--out", str(out)])
    captured = capsys.readouterr()
    assert status == 1
    (line,) = captured.err.splitlines()
    assert line.startswith("error: run stopped at sample 30 (t=30 s): rig fault:")
    assert "lamp driver burnt out" in line
    assert "made safe; 30 samples kept in" in line
    assert "(rig_fault)" in captured.out  # the summary of what was identified still prints
    assert len(_rows(out)) == 30
    (rig,) = rigs
    assert isinstance(rig, TwinRig)
    assert rig.applied_input == 0.0


def test_emulated_tclab_that_stops_answering(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], opened: Callable[..., list[Rig]]
) -> None:
    out = tmp_path / "kit.csv"
    with TCLabEmulator(seed=0) as emulator:
        opened(reset_wait=0.0, timeout=0.2)

        def go_silent() -> None:
            while len(emulator.commands) < 24:  # VER, X, WDOG, then ~7 samples of T1, T2, Q1
                time.sleep(0.005)
            emulator.silent = True

        breaker = threading.Thread(target=go_silent, daemon=True)
        breaker.start()
        status = main(
            ["run", "--rig", f"tclab:{emulator.port}", "--dt", "0.05", "--samples", "400",
             "--signal", "const:80", "--method", "srm", "--out", str(out)]
        )  # fmt: skip
        breaker.join(5.0)
        captured = capsys.readouterr()
        assert status == 1
        (line,) = captured.err.splitlines()
        assert "run stopped at sample" in line
        assert "did not answer" in line
        rows = _rows(out)
        assert 5 <= len(rows) < 400
        assert {r["u"] for r in rows} == {"80.0"}
        # Commands are still obeyed while the kit is silent: the heater went off.
        assert emulator.heater(1) == 0.0


def test_interlock_on_the_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status = main([*FAST_STEP, "--signal", "const:10", "--method", "lsm", "--max-output", "1"])
    captured = capsys.readouterr()
    assert status == 1
    assert "interlock: output" in captured.err
    assert "above the limit of 1 V" in captured.err


def test_sigint_exits_130_after_the_safe_state(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], opened: Callable[..., list[Rig]]
) -> None:
    class Interrupted(TwinRig):
        def _read_output(self) -> Reading:
            if self.clock.now() >= 20.0:
                raise KeyboardInterrupt
            return super()._read_output()

    def swap(rig: Rig) -> None:
        rig.__class__ = Interrupted

    rigs = opened(swap)
    out = tmp_path / "run.csv"
    status = main([*FAST_STEP, "--signal", "const:10", "--method", "srm", "--out", str(out)])
    captured = capsys.readouterr()
    assert status == 130
    (line,) = captured.err.splitlines()
    assert line == f"interrupted by SIGINT: twin:paper made safe; 20 samples kept in {out}"
    assert len(_rows(out)) == 20
    (rig,) = rigs
    assert isinstance(rig, TwinRig)
    assert rig.applied_input == 0.0


def test_sigterm_exits_143_and_keeps_the_csv(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "thermolab", "run", "--rig", "sim", "--dt", "0.05", "--samples",
         "100000", "--signal", "const:10", "--method", "srm", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:
            if out.exists() and len(out.read_text().splitlines()) > 5:
                break
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30.0)
    finally:
        proc.kill()
    assert proc.returncode == 143
    (line,) = err.splitlines()
    assert line.startswith("interrupted by SIGTERM: twin:paper made safe;")
    rows = _rows(out)
    assert len(rows) >= 5
    assert line.endswith(f"{len(rows)} samples kept in {out}")


@pytest.mark.parametrize(
    ("args", "status", "message"),
    [
        (["--rig", "tclab:/dev/null", "--fast"], 2, "runs in real time"),
        (["--method", "srm,lsm", "--gamma", "0.9"], 1, "gamma is a setting of wlsm"),
        (["--method", "rls"], 1, "unknown method 'rls'"),
        (["--signal", "square:4:6"], 1, "invalid signal 'square:4:6'"),
        (["--signal", "const:12"], 1, "const:12"),
        (["--dt", "0"], 2, "--dt must be a positive number"),
        (["--samples", "0"], 2, "--samples must be at least 1"),
        (["--rig", "lab"], 1, "unknown rig 'lab'"),
        (["--watchdog", "0"], 1, "watchdog must be a positive number"),
        (["--method", "lsm", "--window", "0"], 2, "--window must be an integer >= 3"),
        (["--method", "lsm", "--form", "standard"], 1, "form is a setting of wlsm"),
    ],
)
def test_usage_errors_are_one_line(
    args: list[str], status: int, message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    base = {"--rig": "sim", "--signal": "const:1", "--dt": "1", "--samples": "10"}
    argv = ["run", "--fast"] if "--fast" not in args else ["run"]
    for key, value in base.items():
        if key not in args:
            argv += [key, value]
    assert main([*argv, *args]) == status
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1
    assert message in err


def test_duration_shorter_than_a_period(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", "--fast", "--dt", "1", "--duration", "0.5", "--signal", "const:1"]
    assert main(argv) == 1
    assert "shorter than one period" in capsys.readouterr().err


def test_progress_bar_draws_one_line() -> None:
    class Stub:
        k, samples, dt = 500, 2000, 1.0

    stream = io.StringIO()
    Progress(Stub(), stream)._draw(elapsed=2.0)
    text = stream.getvalue()
    assert text.startswith("\r[#######-----------------------]  25%  500/2000 samples  t=500 s")
    assert "ETA    6 s" in text
    assert "\n" not in text


def test_a_method_without_a_model_says_why(capsys: pytest.CaptureFixture[str]) -> None:
    # SRM needs one step; a square wave has many. The run still succeeds.
    argv = [*FAST_STEP[:-2], "500", "--fast", "--signal", "square:4:6:0.1", "--method", "srm,lsm"]
    assert main(argv) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[4:]}
    assert rows["srm"].split()[1:3] == ["-", "-"]
    assert "needs a single step" in rows["srm"]
    assert rows["lsm"].endswith("at END")


def test_any_identifier_setting_reaches_its_methods(capsys: pytest.CaptureFixture[str]) -> None:
    argv = [*FAST_STEP, "--signal", "square:4:6:0.1", "--method", "lsm,wlsm", "--json"]
    assert main([*argv, "--offset", "fit", "--form", "standard", "--p0", "50"]) == 0
    report = json.loads(capsys.readouterr().out)
    # offset="fit" adds the constant to both; p0 would be refused in the paper's form.
    assert len(report["methods"]["lsm"]["latest"]["W"]) == 3
    assert len(report["methods"]["wlsm"]["latest"]["W"]) == 3


# -- closed-loop control (--control pid) --------------------------------------------------

PID_RUN = ["run", "--rig", "sim:tclab", "--dt", "1", "--duration", "1200", "--fast",
           "--seed", "1", "--method", "srm", "--control", "pid"]  # fmt: skip


def test_pid_tuned_from_a_model_prints_measured_and_predicted_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "pid.csv"
    status = main(
        [*PID_RUN, "--setpoint", "step:21:50@60", "--tune", "simc",
         "--model", "0.6,140,15.9", "--out", str(out), "--json"]
    )  # fmt: skip
    assert status == 0
    report = json.loads(capsys.readouterr().out)
    control = report["control"]
    assert control["tuning"]["rule"] == "simc"
    assert_allclose(control["gains"]["Kp"], 140 / (0.6 * 31.8), rtol=1e-12)
    measured = control["closed_loop"]["measured"]
    predicted = control["closed_loop"]["predicted"]
    assert measured["step_time"] == predicted["step_time"] == 60.0
    assert abs(measured["overshoot"] - predicted["overshoot"]) < 3.0
    assert abs(measured["settling_time"] - predicted["settling_time"]) < 30.0
    rows = _rows(out)
    assert list(rows[0])[-5:] == ["r", "u_pid", "e", "auto", "fan"]
    assert float(rows[100]["r"]) == 50.0
    assert abs(float(rows[-1]["y"]) - 50.0) < 0.5


def test_a_loop_closed_at_the_first_sample_is_predicted_from_rest(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # The set point steps at START: the first applied input is already the PID's answer
    # (the heater saturated), so the prediction must start from rest at the safe input.
    status = main(
        [*PID_RUN, "--setpoint", "45", "--tune", "simc", "--model", "0.6,140,15.9", "--json"]
    )
    assert status == 0
    figures = json.loads(capsys.readouterr().out)["control"]["closed_loop"]
    measured, predicted = figures["measured"], figures["predicted"]
    assert measured["step_time"] == predicted["step_time"] == 0.0
    assert_allclose(predicted["step"], measured["step"], rtol=1e-12)
    # The twin is the kit model's two nodes and quantised sensor, the model its FOPDT fit:
    # they agree within a few percent of overshoot and a tenth of the settling time.
    assert abs(measured["overshoot"] - predicted["overshoot"]) < 3.0
    assert_allclose(predicted["settling_time"], measured["settling_time"], rtol=0.1)
    assert_allclose(predicted["iae"], measured["iae"], rtol=0.1)


def test_pid_with_given_gains_prints_a_control_table(capsys: pytest.CaptureFixture[str]) -> None:
    status = main([*PID_RUN, "--setpoint", "40", "--kp", "7", "--ti", "130", "--td", "5"])
    assert status == 0
    out = capsys.readouterr().out
    assert "control: PID auto   set point 40 degC   Kp 7  Ti 130 s  Td 5 s" in out
    assert "measured" in out
    assert "predicted" not in out  # no --model, no prediction


def test_adaptive_pid_from_the_command_line(capsys: pytest.CaptureFixture[str]) -> None:
    status = main(
        # Set-point steps every 200 s: the tuner retunes only from excited, settled intervals.
        ["run", "--rig", "sim", "--dt", "1", "--samples", "2000", "--fast", "--method", "srm",
         "--control", "pid", "--setpoint", "square:0.5:1:0.0025", "--kp", "20", "--ti", "100",
         "--adaptive",
         "--tune", "imc", "--tau-c", "100", "--pid-form", "pi", "--max-change", "0.1",
         "--kp-range", "5,60", "--json"]
    )  # fmt: skip
    assert status == 0
    adaptive = json.loads(capsys.readouterr().out)["control"]["adaptive"]
    assert adaptive["retunes"] > 5
    assert adaptive["skipped"] > 0
    assert adaptive["last_reason"]  # why it holds at the end
    assert adaptive["bounds"]["kp"] == [5.0, 60.0]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--setpoint", "40", "--kp", "nan", "--ti", "100"], "kp must be finite"),
        (["--setpoint", "40", "--kp", "1e9", "--ti", "100"], "kp must be finite"),
        (["--setpoint", "40", "--kp", "5", "--ti", "0"], "ti must be finite"),
        (["--setpoint", "95", "--kp", "5", "--ti", "100"], "outside the rig's output range"),
        (["--setpoint", "step:21:95@10", "--kp", "5", "--ti", "100"], "output range"),
        (["--kp", "5", "--ti", "100"], "needs --setpoint"),
        (["--setpoint", "40"], "needs gains"),
        (["--setpoint", "40", "--kp", "5"], "--kp needs --ti"),
        (["--setpoint", "40", "--tune", "zn", "--model", "0.6,140"], "needs a dead time"),
        (["--setpoint", "40", "--tune", "simc", "--model", "0.6"], "--model takes 2 or 3"),
        (
            ["--setpoint", "40", "--tune", "simc", "--model", "1,2,3", "--pid-form", "pid"],
            "defines the form",
        ),
    ],
)
def test_bad_control_options_are_one_line_errors(
    extra: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    status = main([*PID_RUN, *extra])
    err = capsys.readouterr().err
    assert status in (1, 2)
    (line,) = err.strip().splitlines()
    assert message in line


def test_pid_options_need_control_pid(capsys: pytest.CaptureFixture[str]) -> None:
    status = main([*FAST_STEP, "--signal", "const:1", "--kp", "3"])
    assert status == 2
    assert "--kp need --control pid" in capsys.readouterr().err
    status = main(FAST_STEP)
    assert status == 2
    assert "--signal is required" in capsys.readouterr().err


def test_pid_on_a_rig_without_an_output_unit(
    capsys: pytest.CaptureFixture[str], opened: Callable[..., list[Rig]]
) -> None:
    opened(output_unit="")
    status = main([*PID_RUN, "--setpoint", "40", "--kp", "5", "--ti", "100"])
    assert status == 1
    assert "has no output unit" in capsys.readouterr().err


def test_a_run_on_the_kits_two_heater_twin_records_sensor_2_and_heater_2(tmp_path: Path) -> None:
    out = tmp_path / "kit.csv"
    argv = ["run", "--rig", "sim:kit", "--fast", "--samples", "300", "--seed", "1"]
    status = main([*argv, "--signal", "step:0:50@10", "--method", "lsm", "--out", str(out)])
    assert status == 0
    rows = _rows(out)
    assert list(rows[0])[-2:] == ["t2", "q2"]
    assert {row["q2"] for row in rows} == {"0.0"}  # heater 2 stays off
    assert float(rows[-1]["y"]) > float(rows[-1]["t2"]) + 10.0  # heater 1 warms sensor 1


def test_a_kit_run_identifies_the_pair_chosen_heater_2_to_sensor_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "pair.csv"
    argv = ["run", "--rig", "sim:kit", "--fast", "--samples", "300", "--dt", "2", "--seed", "1"]
    pair = ["--input", "q2", "--output", "t2"]
    status = main([*argv, *pair, "--signal", "step:0:60@20", "--method", "lsm", "--json"])
    assert status == 0
    report = json.loads(capsys.readouterr().out)
    assert report["pair"] == {"input": "q2", "output": "t2"}
    latest = report["methods"]["lsm"]["latest"]
    assert 0.2 < latest["K"] < 0.45, latest  # heater 2 -> sensor 2: half heater 1's 0.6 °C/%
    assert 60.0 < latest["tau"] < 400.0, latest
    status = main([*argv, *pair, "--signal", "step:0:60@20", "--method", "lsm", "--out", str(out)])
    assert status == 0
    assert "identified pair: q2 -> t2" in capsys.readouterr().out
    rows = _rows(out)
    assert {row["u"] for row in rows} == {"0.0"}  # heater 1 rests
    assert rows[-1]["q2"] == "60.0"
    # A name the kit does not have: one line, naming what it has.
    assert main([*argv, "--input", "q3", "--signal", "step:0:60@20", "--method", "lsm"]) == 1
    assert "no channel 'q3'; its inputs: u, q2" in capsys.readouterr().err


def test_a_kit_closed_loop_on_heater_2_from_sensor_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "loop2.csv"
    argv = ["run", "--rig", "sim:kit", "--fast", "--samples", "600", "--dt", "2", "--seed", "1",
            "--control", "pid", "--setpoint", "step:23:35@20", "--kp", "8", "--ti", "160",
            "--model", "0.3,150,10"]  # fmt: skip
    pair = ["--heater", "q2", "--sensor", "t2"]
    assert main([*argv, *pair, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "closed loop: q2 from t2" in said
    rows = _rows(out)
    assert {row["u"] for row in rows} == {"0.0"}  # heater 1 rests: the PID drives heater 2
    assert max(float(row["q2"]) for row in rows) > 10.0
    assert abs(float(rows[-1]["t2"]) - 35.0) < 1.5  # sensor 2 follows the set point
    assert abs(float(rows[-1]["y"]) - 35.0) > 3.0  # sensor 1 does not
    assert main([*argv, *pair, "--json"]) == 0
    control = json.loads(capsys.readouterr().out)["control"]
    assert (control["heater"], control["sensor"]) == ("q2", "t2")
    assert control["closed_loop"]["measured"]["overshoot"] is not None
    assert control["closed_loop"]["predicted"] is not None
    # A pair the rig does not have: one line and status 1; half a pair: a usage error.
    assert main([*argv, "--heater", "q2", "--sensor", "y"]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "no heater and sensor q2/y" in err
    assert main([*argv, "--heater", "q2"]) == 2
    assert "--heater and --sensor go together" in capsys.readouterr().err
    # Only with --control pid.
    assert main(["run", "--rig", "sim:kit", "--fast", "--samples", "5", "--signal", "const:1",
                 "--heater", "q2", "--sensor", "t2"]) == 2  # fmt: skip
    assert "--heater, --sensor need --control pid" in capsys.readouterr().err
    # A one-heater rig has no heater 2 pair.
    one = ["run", "--rig", "sim", "--fast", "--samples", "5", "--control", "pid",
           "--setpoint", "1", "--kp", "1", "--ti", "10", *pair]  # fmt: skip
    assert main(one) == 1
    assert "no heater and sensor q2/t2" in capsys.readouterr().err
