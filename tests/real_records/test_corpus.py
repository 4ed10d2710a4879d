"""The real-record corpus in the suite: references that are not ours, and trust that holds.

Every record of ``../shared/real-records/`` (read by its spec in ``corpus.py``)
is identified by ``thermolab identify`` with each method at its defaults; a
model marked trusted must be within the issue's tolerance of a reference FOPDT
fit written here with SciPy (not ``thermolab.ident``), and the whole-record
methods must be trusted on at least 80 % of the records where they are right.
The held-out records (``Spec.held_out``) took no part in choosing the rules.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

sys.path.insert(0, str(Path(__file__).parent))

import corpus

from thermolab.cli import main as thermolab

pytestmark = pytest.mark.skipif(
    not corpus.FOLDER.is_dir(),
    reason=f"the real-record corpus is absent ({corpus.FOLDER}; CI checks out ../shared)",
)

METHODS = ("srm", "lsm", "oe", "malsm", "wlsm", "blockls")
WHOLE_RECORD = ("srm", "lsm", "oe")
IDS = [s.name for s in corpus.SPECS]


def identify(path: Path, method: str) -> dict[str, Any]:
    """``thermolab identify PATH --method METHOD --json``; ``{"refused": line}`` on exit 1."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = thermolab(["identify", str(path), "--method", method, "--json"])
    if status != 0:
        assert status == 1, err.getvalue()
        assert len(err.getvalue().strip().splitlines()) == 1, "a refusal is one line"
        return {"refused": err.getvalue().strip(), "trusted": False}
    result: dict[str, Any] = json.loads(out.getvalue())
    return result


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str], Any]:
    """Every method on every record: the JSON answer, or the refusal."""
    folder = tmp_path_factory.mktemp("real")
    out: dict[tuple[str, str], Any] = {}
    for spec in corpus.SPECS:
        path = corpus.write_tuy(corpus.load(spec), folder / f"{spec.name.replace(':', '_')}.csv")
        for method in METHODS:
            out[spec.name, method] = identify(path, method)
    return out


def _right(spec: corpus.Spec, s: dict[str, Any]) -> bool:
    return corpus.scipy_fit(spec).right(s.get("K"), s.get("tau"), s.get("theta"))


# --- the references ------------------------------------------------------------------------


def test_a_third_of_the_records_is_held_out() -> None:
    held = [s.name for s in corpus.SPECS if s.held_out]
    assert held == ["kantor_step01", "apm_arduino_data_step_test", "apm_arduino_mimo_data:T2"]
    assert len(held) >= len(corpus.SPECS) // 3


@pytest.mark.parametrize("spec", corpus.SPECS, ids=IDS)
def test_the_reader_spec_reads_the_record_as_recorded(spec: corpus.Spec) -> None:
    d = corpus.load(spec)
    assert d.t.size > 400
    assert (np.diff(d.t) > 0).all()
    assert np.ptp(d.u) > 0, "the heater moves (after the rest the notebook assumes)"
    assert np.ptp(d.y) > 10 * (0.32 if spec.y_unit != "°F" else 0.58)


def test_the_formula_is_exact_for_a_known_model() -> None:
    t = np.array([0.0, 0.7, 1.9, 3.0, 10.0, 30.0])
    u = np.array([0.0, 10.0, 10.0, 10.0, 10.0, 10.0])
    y = corpus.fopdt_response(t, u, 0.5, 4.0, 1.0, 20.0)
    expect = 20.0 + 5.0 * -np.expm1(-np.maximum(t - 1.7, 0.0) / 4.0)
    assert_allclose(y, expect, rtol=0, atol=1e-12)


def test_the_scipy_fit_matches_kantors_published_figures() -> None:
    """Kantor's notebook (SOURCE.md): K ≈ 0.697 °C/%, 163 s to 63 % (delay included)."""
    spec = next(s for s in corpus.SPECS if s.name == "kantor_Step_Test_Data")
    fit = corpus.scipy_fit(spec)
    assert_allclose(fit.K, 0.697, rtol=0.03)
    assert_allclose(fit.tau + fit.theta, 163.0, rtol=0.05)


@pytest.mark.parametrize("spec", corpus.SPECS, ids=IDS)
def test_the_scipy_fit_recovers_its_own_simulation(spec: corpus.Spec) -> None:
    """Noise-free data from the fitted model, at the record's time stamps, gives the model back."""
    d = corpus.load(spec)
    fit = corpus.scipy_fit(spec)
    rng = np.random.default_rng(21)
    y = corpus.fopdt_response(d.t, d.u, fit.K, fit.tau, fit.theta, fit.y0)
    y = y + rng.normal(0.0, 0.05, y.size)
    refit = _fit_arrays(d.t, d.u, y)
    assert_allclose(refit[:2], [fit.K, fit.tau], rtol=0.02)
    assert abs(refit[2] - fit.theta) < 1.0


def _fit_arrays(t: np.ndarray, u: np.ndarray, y: np.ndarray) -> np.ndarray:
    from scipy.optimize import least_squares

    def residual(p: np.ndarray) -> np.ndarray:
        r: np.ndarray = corpus.fopdt_response(t, u, p[0], p[1], p[2], p[3]) - y
        return r

    best = min(
        (
            least_squares(
                residual, [np.ptp(y) / np.ptp(u), 100.0, th, y[0]],
                bounds=([-np.inf, 1.0, 0.0, -np.inf], [np.inf, 1e4, 120.0, np.inf]),
            )
            for th in (0.0, 10.0, 25.0)
        ),
        key=lambda r: r.cost,
    )  # fmt: skip
    fitted: np.ndarray = np.asarray(best.x, dtype=np.float64)
    return fitted


@pytest.mark.slow
@pytest.mark.parametrize("name", ["apm_pds_TCLab_data", "kantor_step01"])
def test_the_peer_package_agrees_with_the_scipy_fit(name: str) -> None:
    pytest.importorskip("control")
    spec = next(s for s in corpus.SPECS if s.name == name)
    ours, peer = corpus.scipy_fit(spec), corpus.control_fit(spec)
    assert_allclose([peer.K, peer.tau], [ours.K, ours.tau], rtol=0.03)
    assert abs(peer.theta - ours.theta) < 5.0


# --- trust that holds ---------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_a_trusted_model_is_right(method: str, outcomes: dict[tuple[str, str], Any]) -> None:
    wrong_but_trusted = [
        spec.name
        for spec in corpus.SPECS
        if (s := outcomes[spec.name, method])["trusted"] and not _right(spec, s)
    ]
    assert wrong_but_trusted == []


@pytest.mark.parametrize("method", WHOLE_RECORD)
def test_a_right_whole_record_model_is_trusted(
    method: str, outcomes: dict[tuple[str, str], Any]
) -> None:
    right = [s for spec in corpus.SPECS if _right(spec, s := outcomes[spec.name, method])]
    assert right, f"{method} is right on no record"
    trusted = [s for s in right if s["trusted"]]
    assert len(trusted) >= 0.8 * len(right), (method, len(trusted), len(right))


@pytest.mark.parametrize("method", METHODS)
def test_every_untrusted_answer_says_why(method: str, outcomes: dict[tuple[str, str], Any]) -> None:
    for spec in corpus.SPECS:
        s = outcomes[spec.name, method]
        if s["trusted"]:
            continue
        reasons = [s["refused"]] if "refused" in s else s["verdict"]["reasons"]
        assert reasons, (spec.name, method)
        assert all(isinstance(r, str) and "\n" not in r for r in reasons)


@pytest.mark.parametrize("method", ["lsm", "malsm", "wlsm", "blockls"])
def test_the_arx_dead_time_agrees_with_the_fopdt_one_or_is_flagged(
    method: str, outcomes: dict[tuple[str, str], Any]
) -> None:
    for spec in corpus.SPECS:
        s = outcomes[spec.name, method]
        if s.get("theta") is None:
            continue
        if abs(s["theta"] - corpus.scipy_fit(spec).theta) > corpus.THETA_TOL:
            assert not s["trusted"], (spec.name, method)


@pytest.mark.parametrize("method", ["malsm", "wlsm", "blockls"])
def test_offline_methods_answer_on_a_complete_record(
    method: str, outcomes: dict[tuple[str, str], Any]
) -> None:
    for spec in corpus.SPECS:
        s = outcomes[spec.name, method]
        assert "have arrived" not in (s.get("reason") or s.get("refused") or ""), spec.name


# --- the user's files as they come --------------------------------------------------------

AS_RECORDED = [s for s in corpus.SPECS if not s.rest_before and s.name != "kantor_Step_Test_Data"]


@pytest.mark.parametrize("spec", AS_RECORDED, ids=[s.name for s in AS_RECORDED])
def test_read_record_takes_the_file_with_a_column_map(spec: corpus.Spec) -> None:
    """Positions from 1, a header or none: the same numbers as the spec's NumPy reader."""
    from thermolab.records import read_record

    where = ",".join(f"{k}={j + 1}" for k, j in zip("tuy", spec.columns, strict=True))
    r = read_record(spec.path, columns=where, channels=())
    d = corpus.load(spec)
    for mine, theirs in ((r.t, d.t), (r.u, d.u), (r.y, d.y)):
        assert_allclose(mine, theirs, rtol=1e-15, atol=0)


def test_the_tclab_historian_layout_is_read_without_options(tmp_path: Path) -> None:
    """Kantor's record is a Historian CSV (Time,T1,T2,Q1): heater 1, in s, % and °C."""
    spec = next(s for s in corpus.SPECS if s.name == "kantor_StepTestData")
    code, s = _cli(spec.path, "oe")
    assert code == 0
    assert s["units"] == {"t": "s", "u": "%", "y": "°C", "K": "°C/%", "tau": "s", "theta": "s"}
    assert s["trusted"]
    assert corpus.scipy_fit(spec).right(s["K"], s["tau"], s["theta"])


@pytest.mark.parametrize("method", METHODS)
def test_no_volts_on_a_record_in_percent_and_degrees(method: str, tmp_path: Path) -> None:
    spec = next(s for s in corpus.SPECS if s.name == "apm_pds_TCLab_data")
    code, s = _cli(spec.path, method, "--columns", "t=time,u=Q,y=T", "--units", "u=%,y=°C")
    text = json.dumps(s, ensure_ascii=False) if code == 0 else s["refused"]
    assert " V" not in text.replace(" V0", "")
    assert "volts" not in text


def _cli(path: Path, method: str, *options: str) -> tuple[int, dict[str, Any]]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = thermolab(["identify", str(path), "--method", method, *options, "--json"])
    return code, (json.loads(out.getvalue()) if code == 0 else {"refused": err.getvalue()})


@pytest.mark.parametrize("name", ["kantor_step01", "che436_step_test"])
def test_the_same_timing_warnings_whichever_method(
    name: str, outcomes: dict[tuple[str, str], Any]
) -> None:
    """Irregular records: every method that answers gives the same jitter and gap warnings."""
    seen = set()
    for method in METHODS:
        s = outcomes[name, method]
        if "refused" in s:
            continue
        timing = tuple(w for w in s["warnings"] if w.startswith(("timing jitter", "gap in time")))
        assert len(timing) == 2, (method, s["warnings"])
        seen.add(timing)
    assert len(seen) == 1
