"""``thermolab identify`` end to end: methods, output forms and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from thermolab.cli import main
from thermolab.signals import parse_signal
from thermolab.simulation import PAPER_W0, REFERENCE_MODEL

K_REF, TAU_REF = REFERENCE_MODEL.K, REFERENCE_MODEL.tau
Run = Callable[..., tuple[int, str, str]]


def _write(path: Path, columns: dict[str, np.ndarray], header: str | None = None) -> Path:
    names = list(columns)
    lines = [header if header is not None else ",".join(names)]
    for row in zip(*(columns[n].tolist() for n in names), strict=True):
        lines.append(",".join(repr(v) for v in row))
    path.write_text("\n".join(lines) + "\n")
    return path


def _record(spec: str, n: int, noise: float = 0.0) -> dict[str, np.ndarray]:
    t = np.arange(float(n))
    u = parse_signal(spec).sample(t)
    y = REFERENCE_MODEL.simulate(u)
    if noise:
        y = y + np.random.default_rng(0).normal(0.0, noise, n)
    return {"t": t, "u": u, "y": y}


@pytest.fixture
def step_csv(tmp_path: Path) -> Path:
    return _write(tmp_path / "step.csv", _record("step:0:10@1", 2000))


@pytest.fixture
def square_csv(tmp_path: Path) -> Path:
    return _write(tmp_path / "square.csv", _record("square:0:4:0.1", 4000))


@pytest.fixture
def run(capsys: pytest.CaptureFixture[str]) -> Run:
    def call(*argv: str) -> tuple[int, str, str]:
        status = main(["identify", *argv])
        out, err = capsys.readouterr()
        return status, out, err

    return call


def _json(run: Run, *argv: str) -> dict[str, Any]:
    status, out, err = run(*argv, "--json")
    assert status == 0, err
    assert len(out.strip().splitlines()) == 1
    result: dict[str, Any] = json.loads(out)
    return result


# --- methods -----------------------------------------------------------------------------


def test_srm_reproduces_table1(run: Run, step_csv: Path) -> None:
    d = _json(run, str(step_csv), "--method", "srm")
    assert d["method"] == "srm"
    assert d["dt"] == 1.0
    assert round(d["K_last_sample"], 6) == 0.140042
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=1e-10)
    assert d["warnings"] == []
    assert d["n_samples"] == 2000


def test_lsm(run: Run, step_csv: Path) -> None:
    d = _json(run, str(step_csv), "--method", "lsm")
    assert d["method"] == "lsm"
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=1e-8)
    assert "stats" not in d
    assert "converged_at" not in d


def test_blockls_has_stats_but_no_convergence(run: Run, square_csv: Path) -> None:
    d = _json(run, str(square_csv), "--method", "blockls", "--block", "100")
    assert set(d["stats"]) == {"K", "tau"}
    assert set(d["stats"]["K"]) == {"mean", "max", "min"}
    assert_allclose(d["stats"]["tau"]["mean"], TAU_REF, rtol=1e-8)
    assert "converged_at" not in d
    assert d["params"]["block"] == 100


def test_malsm(run: Run, square_csv: Path) -> None:
    d = _json(run, str(square_csv), "--method", "malsm", "--window", "50")
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=1e-8)
    assert set(d["converged_at"]) == {"K", "tau"}
    assert all(isinstance(v, int) for v in d["converged_at"].values())
    assert d["params"]["window"] == 50


def test_wlsm_paper_settings(run: Run, square_csv: Path) -> None:
    w0 = ",".join(str(v) for v in PAPER_W0)
    d = _json(
        run, str(square_csv), "--method", "wlsm", "--gamma", "0.7", "--pmax", "1e4", "--w0", w0
    )
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=1e-6)
    assert d["converged_at"]["K"] < 200
    assert d["params"]["gamma"] == 0.7
    assert d["params"]["form"] == "paper"
    assert d["stats"]["K"]["min"] <= d["stats"]["K"]["mean"] <= d["stats"]["K"]["max"]


def test_wlsm_standard_form_with_p0(run: Run, square_csv: Path) -> None:
    argv = ["--method", "wlsm", "--form", "standard", "--gamma", "0.98", "--p0", "1e4"]
    d = _json(run, str(square_csv), *argv)
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=1e-6)
    assert d["params"]["form"] == "standard"
    assert d["params"]["p0"] == [[1e4, 0.0], [0.0, 1e4]]


def test_offset_and_order_reach_the_method(run: Run, tmp_path: Path) -> None:
    rec = _record("prbs:0:5:20:3", 3000)
    rec["y"] = rec["y"] + 2.5  # an ambient operating point
    path = _write(tmp_path / "warm.csv", rec)
    d = _json(run, str(path), "--method", "lsm", "--offset", "fit")
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=1e-6)
    assert d["offset"] == "fit"
    d = _json(run, str(path), "--method", "lsm", "--offset", "2.5")
    assert d["offset"] == 2.5
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=1e-8)
    # Exact first-order data leave a second-order model undetermined; a little noise does not.
    noisy = _write(tmp_path / "noisy.csv", _record("prbs:0:5:20:3", 3000, noise=1e-4))
    d = _json(run, str(noisy), "--method", "lsm", "--order", "2,2,0", "--offset", "none")
    assert d["order"] == {"na": 2, "nb": 2, "delay": 0}
    assert d["param_names"] == ["a1", "a2", "b1", "b2"]
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=0.05)


def test_dt_defaults_to_the_median_spacing(run: Run, tmp_path: Path) -> None:
    rec = _record("square:0:4:0.05", 3000)
    rec["t"] = rec["t"] * 2.0
    path = _write(tmp_path / "slow.csv", rec)
    d = _json(run, str(path), "--method", "lsm")
    assert d["dt"] == 2.0
    assert_allclose(d["tau"], 2.0 * TAU_REF, rtol=1e-8)
    d = _json(run, str(path), "--method", "lsm", "--dt", "1")
    assert d["dt"] == 1.0
    assert_allclose(d["tau"], TAU_REF, rtol=1e-8)


def test_columns_in_any_order_extra_columns_and_comments(run: Run, tmp_path: Path) -> None:
    rec = _record("step:0:10@1", 2000)
    path = tmp_path / "messy.csv"
    body = "\n".join(
        f"{k},{y!r},x,{u!r},{t!r}"
        for k, (t, u, y) in enumerate(
            zip(rec["t"].tolist(), rec["u"].tolist(), rec["y"].tolist(), strict=True)
        )
    )
    path.write_text(f"# recorded by a test\nk, Y ,note,U,T\n{body}\n\n")
    d = _json(run, str(path), "--method", "srm")
    assert round(d["K_last_sample"], 6) == 0.140042


def test_warnings_in_json_and_on_stderr(run: Run, tmp_path: Path) -> None:
    path = _write(tmp_path / "short.csv", _record("step:0:10@1", 500))
    d = _json(run, str(path), "--method", "srm")
    kinds = [w.split(":")[0] for w in d["warnings"]]
    assert kinds == ["not settled", "short record"]
    status, out, err = run(str(path), "--method", "srm")
    assert status == 0
    assert "K (paper, last sample)" in out
    assert err.count("warning: ") == 2


def test_readable_tables(run: Run, square_csv: Path, step_csv: Path) -> None:
    status, out, _ = run(str(square_csv), "--method", "wlsm", "--gamma", "0.7")
    assert status == 0
    assert "converged at" in out
    assert "tau (s)" in out
    # The paper's count by default (issue #8 item 7); --last asks for the last N samples.
    assert "samples after convergence, ±1 %)" in out
    assert "trusted          yes" in out
    status, out, _ = run(str(square_csv), "--method", "wlsm", "--gamma", "0.7", "--last", "2000")
    assert "statistics over the last 2000 samples" in out
    status, out, _ = run(str(step_csv), "--method", "srm")
    assert "0.140042" in out
    assert "250.126233" in out


def test_plot(run: Run, step_csv: Path, square_csv: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    for method, path in (("srm", step_csv), ("malsm", square_csv)):
        out = tmp_path / f"{method}.png"
        status, _, err = run(str(path), "--method", method, "--plot", str(out))
        assert status == 0, err
        assert out.stat().st_size > 1000
    status, _, err = run(str(step_csv), "--method", "srm", "--plot", str(tmp_path / "no" / "x.png"))
    assert status == 1
    assert err.startswith("error: --plot: cannot write")


# --- errors ------------------------------------------------------------------------------


def _one_line_error(run: Run, *argv: str, status: int = 1) -> str:
    code, out, err = run(*argv)
    assert code == status, err
    assert out == ""
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err
    assert err.startswith("error: ")
    return err.strip()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "empty file"),
        (b"a,b,c\n1,2,3\n", "lacks the columns t, u, y"),
        (b"t,u\n0,1\n1,1\n2,1\n", "lacks the column y"),
        (b"t,u,y\n0,0,0\n1,1,0\n", "too few rows: 2 samples, at least 3"),
        (b"t,u,y\n0,0,0\n1,1,0\n2,abc,0\n3,1,1\n", "line 4 (sample 2), column u: 'abc' is not"),
        (b"t,u,y\n0,0,0\n1,1,nan\n2,1,0\n", "line 3 (sample 1), column y: 'nan' is not finite"),
        (b"t,u,y\n0,0,0\n1,1\n2,1,0\n", "line 3 (sample 1) has 2 cells"),
        # Equal times are merged (see below); a time that goes back is refused.
        (b"t,u,y\n0,0,0\n1,1,0\n0.5,1,0\n", "line 4 (sample 2): t = 0.5 does not increase"),
        (b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe", "not a CSV text file"),
    ],
)
def test_bad_files(run: Run, tmp_path: Path, content: bytes, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(content)
    err = _one_line_error(run, str(path), "--method", "lsm")
    assert message in err
    assert str(path) in err


def test_missing_file_and_directory(run: Run, tmp_path: Path) -> None:
    assert "no such file" in _one_line_error(run, str(tmp_path / "nope.csv"), "--method", "srm")
    assert "is a directory" in _one_line_error(run, str(tmp_path), "--method", "srm")


def test_method_errors_are_one_line(run: Run, square_csv: Path, tmp_path: Path) -> None:
    err = _one_line_error(run, str(square_csv), "--method", "srm")
    assert "the input changes more than once" in err
    err = _one_line_error(run, str(square_csv), "--method", "wlsm", "--gamma", "1")
    assert "gamma = 1 is not allowed in the paper's form" in err
    flat = _write(tmp_path / "flat.csv", _record("const:0", 300))
    for method in ("srm", "lsm", "oe", "malsm", "wlsm", "blockls"):
        # One refusal for bad input, whichever method is asked (issue #21).
        err = _one_line_error(run, str(flat), "--method", method)
        assert "no excitation: the input never changes" in err


def test_too_few_samples_and_a_flat_output_are_refused_alike(run: Run, tmp_path: Path) -> None:
    short = tmp_path / "short.csv"
    short.write_text("t,u,y\n" + "".join(f"{k},{5.0 * (k >= 3)},{0.1 * k}\n" for k in range(12)))
    dead = tmp_path / "dead.csv"
    dead.write_text("t,u,y\n" + "".join(f"{k},{5.0 * (k >= 30)},1.5\n" for k in range(300)))
    for method in ("srm", "lsm", "oe", "malsm", "wlsm", "blockls"):
        assert "too few samples: 12" in _one_line_error(run, str(short), "--method", method)
        assert "flat output" in _one_line_error(run, str(dead), "--method", method)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--method", "srm", "--window", "10"], "--window does not apply to --method srm"),
        (["--method", "lsm", "--gamma", "0.9"], "--gamma does not apply to --method lsm"),
        (["--method", "srm", "--offset", "fit"], "--offset does not apply to --method srm"),
        (["--method", "blockls", "--tol", "0.1"], "--tol does not apply"),
        (["--method", "malsm", "--window", "0"], "--window must be an integer >= 3"),
        (["--method", "wlsm", "--gamma", "abc"], "--gamma must be a finite number > 0 and <= 1"),
        (["--method", "lsm", "--order", "1,2"], "--order must be three whole numbers"),
        (
            ["--method", "lsm", "--offset", "warm"],
            "--offset must be one of auto, initial, fit, none or a finite number",
        ),
        (["--method", "lsm", "--dt", "-1"], "--dt must be > 0"),
        (["--method", "fast"], "invalid choice: 'fast'"),
        ([], "the following arguments are required: --method"),
    ],
)
def test_usage_errors_exit_2(run: Run, step_csv: Path, argv: list[str], message: str) -> None:
    assert message in _one_line_error(run, str(step_csv), *argv, status=2)


def test_invalid_order_value_exit_1(run: Run, step_csv: Path) -> None:
    err = _one_line_error(run, str(step_csv), "--method", "lsm", "--order", "0,1,0")
    assert "na (number of output lags)" in err


def test_subprocess(step_csv: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "thermolab", "identify", str(step_csv), "--method", "lsm", "--json"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    assert_allclose([d["K"], d["tau"]], [K_REF, TAU_REF], rtol=1e-8)
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "thermolab",
            "identify",
            str(step_csv) + ".missing",
            "--method",
            "lsm",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert bad.returncode == 1
    assert bad.stderr.count("\n") == 1
    assert "no such file" in bad.stderr


def test_wlsm_defaults_are_the_papers(run: Run, square_csv: Path) -> None:
    # The registry's WLSM defaults: gamma 0.96, pmax 1e4 and the paper's W0 (as on the lab's page).
    w0 = ",".join(str(v) for v in PAPER_W0)
    plain = _json(run, str(square_csv), "--method", "wlsm")
    spelled = _json(
        run, str(square_csv), "--method", "wlsm", "--gamma", "0.96", "--pmax", "1e4", "--w0", w0
    )
    assert plain == spelled
    assert plain["params"]["w0"] == list(PAPER_W0)


def test_step_response_settings_reach_the_method(run: Run, tmp_path: Path) -> None:
    path = _write(tmp_path / "short.csv", _record("step:0:10@1", 800))
    flagged = _json(run, str(path), "--method", "srm")
    assert any(w.startswith("short record") for w in flagged["warnings"])
    quiet = _json(run, str(path), "--method", "srm", "--min-samples", "0")
    assert not any(w.startswith("short record") for w in quiet["warnings"])
    assert quiet["K"] == flagged["K"]


def test_registered_settings_are_checked_at_the_command_line(run: Run, step_csv: Path) -> None:
    err = _one_line_error(run, str(step_csv), "--method", "wlsm", "--gamma", "1.5", status=2)
    assert "--gamma must be a finite number > 0 and <= 1, got '1.5'" in err
    err = _one_line_error(run, str(step_csv), "--method", "srm", "--min-step", "-1", status=2)
    assert "--min-step must be a finite number >= 0" in err
    err = _one_line_error(run, str(step_csv), "--method", "lsm", "--min-step", "2", status=2)
    assert "--min-step does not apply to --method lsm (it applies to srm)" in err


# --- records from spreadsheets ---------------------------------------------------------------


def test_a_brazilian_spreadsheet_export_gives_the_same_model(
    run: Run, step_csv: Path, tmp_path: Path
) -> None:
    # ";" separators, decimal commas, a byte-order mark and CRLF line ends.
    text = step_csv.read_text().replace(",", ";").replace(".", ",").replace("\n", "\r\n")
    sheet = tmp_path / "planilha.csv"
    sheet.write_bytes("\ufeff".encode() + text.encode())
    plain, sheet_out = (
        _json(run, str(step_csv), "--method", "lsm"),
        _json(run, str(sheet), "--method", "lsm"),
    )
    assert sheet_out["K"] == plain["K"]
    assert sheet_out["tau"] == plain["tau"]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"t;u;y\n0;0,5;1.5\n1;1;0\n2;1;0\n", "ambiguous decimal mark"),
        (b"t,u,y\n0,0,0\n1,1,5,1\n2,1,0\n", "decimal commas need a ';' or tab separator"),
        (b"\xff\xfet\x00,\x00", "UTF-16"),
    ],
)
def test_spreadsheet_problems_are_one_line(
    run: Run, tmp_path: Path, content: bytes, message: str
) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(content)
    assert message in _one_line_error(run, str(path), "--method", "lsm")


def _fopdt_step(n: int = 700) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A kit-like step in % and °C (0.6 °C/%, 140 s, 15 s), 0.05 °C of seeded noise."""
    from thermolab.ident.oe import simulate_fopdt_at

    t = np.arange(float(n))
    u = np.where(t >= 20, 50.0, 0.0)
    noise = np.random.default_rng(21).normal(0.0, 0.05, n)
    return t, u, 21.0 + simulate_fopdt_at(t, u, 0.6, 140.0, 15.0) + noise


@pytest.mark.parametrize(
    ("header", "options"),
    [
        ("Time (s),Q1 (%),T1 (°C),T2 (°C)", ["--columns", "t=Time,u=Q1,y=T1"]),
        ("time [sec],heater,temperature (degC),T2", ["--columns", "t=1,u=heater,y=3",
                                                    "--units", "u=%"]),
        (None, ["--columns", "t=1,u=2,y=3", "--units", "u=%,y=°C"]),
        ("Time,T1,T2,Q1,Q2", []),  # the tclab Historian's layout, recognised
    ],
)  # fmt: skip
def test_columns_by_name_or_position_and_units_from_the_header(
    run: Run, tmp_path: Path, header: str | None, options: list[str]
) -> None:
    t, u, y = _fopdt_step()
    order = (t, y, y - 1.0, u, 0 * u) if header == "Time,T1,T2,Q1,Q2" else (t, u, y, y - 1.0)
    rows = zip(*order, strict=True)
    body = "".join(",".join(repr(float(v)) for v in row) + "\n" for row in rows)
    path = tmp_path / "kit.csv"
    path.write_text(("" if header is None else header + "\n") + body, encoding="utf-8")
    code, out, err = run(str(path), "--method", "oe", *options, "--json")
    assert code == 0, err
    s = json.loads(out)
    assert s["units"]["K"] == "°C/%"
    assert_allclose([s["K"], s["tau"], s["theta"]], [0.6, 140.0, 15.0], rtol=0.03, atol=0.5)
    assert s["trusted"]
    assert " V" not in json.dumps(s, ensure_ascii=False)


def test_a_bad_column_map_is_one_line(run: Run, tmp_path: Path) -> None:
    path = tmp_path / "kit.csv"
    path.write_text("Time,Q1,T1\n0,0,20\n1,50,20\n2,50,20.3\n")
    err = _one_line_error(run, str(path), "--method", "lsm", "--columns", "t=Time,u=Q9,y=T1")
    assert "u='Q9'" in err
    assert "names no such column" in err
    err = _one_line_error(run, str(path), "--method", "lsm", "--columns", "t=Time,u=Q1")
    assert "lacks y" in err
    err = _one_line_error(run, str(path), "--method", "lsm", "--columns", "t=1,u=2,y=7")
    assert "has 3 columns" in err


def test_a_duplicated_time_is_merged_and_said_whichever_method(run: Run, tmp_path: Path) -> None:
    t, u, y = _fopdt_step()
    rows = [(0.0, 0.0, float(y[0])), *zip(t.tolist(), u.tolist(), y.tolist(), strict=True)]
    path = tmp_path / "dup.csv"
    path.write_text("t,u,y\n" + "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in rows))
    for method in ("lsm", "oe", "malsm", "wlsm", "blockls", "srm"):
        code, out, err = run(str(path), "--method", method, "--json")
        assert code == 0, err
        s = json.loads(out)
        assert s["n_samples"] == t.size
        assert any(w.startswith("duplicated time: 1 row") for w in s["warnings"]), method


def test_a_saturated_input_is_refused_alike(run: Run, tmp_path: Path) -> None:
    t, u, y = _fopdt_step()
    path = tmp_path / "sat.csv"
    rows = zip(t.tolist(), (2.5 * u).tolist(), y.tolist(), strict=True)
    path.write_text("t,Q1 (%),T1 (°C)\n" + "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in rows))
    for method in ("srm", "lsm", "oe", "malsm", "wlsm", "blockls"):
        err = _one_line_error(run, str(path), "--method", method, "--columns", "t=t,u=Q1,y=T1")
        assert "saturated input: the record asks the heater for 125 %" in err


# --- the reader's language ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("lang", "said"),
    [
        ("pt_BR.UTF-8", ["método   srm (resposta ao degrau)", "valor final", "(aquecimento)"]),
        ("es_ES.UTF-8", ["método   srm (respuesta al escalón)", "valor final", "(calentamiento)"]),
    ],
)
def test_the_report_speaks_the_users_language_with_its_decimal_mark(
    run: Run,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    lang: str,
    said: list[str],
) -> None:
    # Issue #24: the command line was English but for its errors. A short record, so a
    # warning of the library is said too, as the browser says it.
    record = _write(tmp_path / "short.csv", _record("step:0:10@1", 1500))
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LANG", lang)
    status, out, err = run(str(record), "--method", "srm")
    assert status == 0, err
    for words in said:
        assert words in out, out
    assert "0,1400" in out  # Ks with the decimal comma
    assert "0.1400" not in out
    english = {"method", "file", "final value", "heating", "step response", "yes", "settled"}
    assert not [w for w in english if f" {w} " in f" {out} "], out
    warning = "aviso: registro curto: " if lang.startswith("pt") else "aviso: registro corto: "
    assert err.startswith(warning), err
    # The operating point's decision without the library's English reasoning.
    status, out, err = run(str(record), "--method", "lsm")
    assert status == 0, err
    assert "offset=" in out
    assert "the record starts" not in out
    assert "subtracting" not in out
    # JSON stays the same in every language: it is for programs.
    status, out, _err = run(str(record), "--method", "srm", "--json")
    assert json.loads(out)["method"] == "srm"
    assert '"K": 0.14' in out


def test_help_and_argparse_speak_the_users_language(
    run: Run, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LANG", "es_ES.UTF-8")
    with pytest.raises(SystemExit):
        main(["identify", "--help"])
    out = capsys.readouterr().out
    assert out.startswith("uso: thermolab identify")
    assert "muestra esta ayuda y sale" in out
    assert main(["identify", "x.csv", "--method", "nope"]) == 2
    assert "opción no válida: 'nope'" in capsys.readouterr().err


def test_why_a_record_gives_no_model_is_said_in_the_users_language(
    run: Run, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A real kit's record whose heater never moved: the reason's detail was English.
    record = _write(tmp_path / "flat.csv", _record("const:5", 300))
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LANG", "pt_BR.UTF-8")
    status, _out, err = run(str(record), "--method", "srm")
    assert status == 1
    assert "(sem excitação: a entrada nunca muda (fica em 5), então nenhum método" in err
