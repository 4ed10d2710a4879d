"""The paper's Table I: the rows that must match, the orders of magnitude, the variants."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from numpy.testing import assert_allclose

from thermolab.errors import InvalidParameterError
from thermolab.ident import weighted_least_squares
from thermolab.reproduction import (
    DAQ_16BIT_QUANTUM,
    TABLE1_ROWS,
    Stats,
    Table1Options,
    Table1Result,
    reproduce_table1,
)
from thermolab.signals import parse_signal
from thermolab.simulation import PAPER_W0, REFERENCE_MODEL

MATCHING = ("SRM", "LSM(1)", "LSM(3)", "MALSM")
WLSM_04 = ("WLSM(1)", "WLSM(2)", "WLSM(3)")
WLSM_46 = ("WLSM(4)", "WLSM(5)", "WLSM(6)")
TAU_REF = REFERENCE_MODEL.tau


@pytest.fixture(scope="module")
def exact() -> Table1Result:
    return reproduce_table1()


@pytest.fixture(scope="module")
def paper_arithmetic() -> Table1Result:
    return reproduce_table1(solver="explicit-inverse", covariance="frozen")


def _six(stats_k: Stats, stats_tau: Stats) -> list[float]:
    return [v for s in (stats_k, stats_tau) for _, v in s.items()]


# --- the rows that must match the printed digits ---------------------------------------


@pytest.mark.parametrize("run", MATCHING)
def test_matching_rows_equal_the_printed_digits(exact: Table1Result, run: str) -> None:
    row = exact.row(run)
    ours = _six(row.ours.K, row.ours.tau)
    paper = _six(row.paper.K, row.paper.tau)
    # Rounded to the paper's 6 decimals, every figure is the printed one.
    assert [round(v, 6) for v in ours] == paper
    assert_allclose(ours, paper, rtol=0, atol=5e-7)
    assert row.digits_match


def test_srm_reports_the_last_sample_gain_and_the_settled_one(exact: Table1Result) -> None:
    row = exact.row("SRM")
    # The paper's 0.140042 is the last sample of a finite record, 48e-6 short of Ks.
    assert_allclose(row.ours.K.mean, 0.1400424361, rtol=0, atol=1e-10)
    assert_allclose(row.ours.K.mean - REFERENCE_MODEL.K, -47.56e-6, rtol=0, atol=1e-8)
    assert any("settled (extrapolated) gain 0.140090" in note for note in row.notes)


def test_exact_simulation_does_not_reproduce_lsm2_minimum(exact: Table1Result) -> None:
    tau = exact.row("LSM(2)").ours.tau
    # A sound solver recovers the exact Ts on every block; the paper's minimum is 5.5 ms low.
    assert_allclose([tau.mean, tau.max, tau.min], TAU_REF, rtol=0, atol=1e-5)
    assert not exact.row("LSM(2)").digits_match


# --- WLSM: orders of magnitude ---------------------------------------------------------


@pytest.mark.parametrize("run", WLSM_04)
def test_wlsm_0_4_converges_in_the_papers_order_of_magnitude(exact: Table1Result, run: str) -> None:
    row = exact.row(run)
    ours, paper = row.ours.converged_at, row.paper.converged_at
    assert ours is not None
    assert paper is not None
    for n, p in ((ours.K, paper.K), (ours.tau, paper.tau)):
        assert n is not None
        assert abs(math.log10(n / p)) <= 0.5, (run, n, p)
    assert row.convergence_order_match


@pytest.mark.parametrize("run", WLSM_04 + WLSM_46)
def test_wlsm_run_lasts_after_convergence_and_stats_cover_it(exact: Table1Result, run: str) -> None:
    row = exact.row(run)
    conv = row.ours.converged_at
    assert conv is not None
    assert conv.K is not None
    assert conv.tau is not None
    assert row.samples == max(conv.K, conv.tau) + 2000 + 1
    assert row.trajectory is not None
    assert row.trajectory.n_samples == row.samples
    window = row.trajectory.tau[-2000:]
    assert_allclose(
        [row.ours.tau.mean, row.ours.tau.max, row.ours.tau.min],
        [window.mean(), window.max(), window.min()],
        rtol=1e-15,
    )
    # The window starts at convergence: nothing in it is further than 1 % off.
    assert np.all(np.abs(window / TAU_REF - 1.0) <= 0.0101)


@pytest.mark.parametrize("run", WLSM_46)
def test_exact_wlsm_4_6_converges_fast_and_unbiased(exact: Table1Result, run: str) -> None:
    # What the paper's 1e4 samples and -1.5 s bias cannot come from: exact RLS.
    row = exact.row(run)
    conv = row.ours.converged_at
    assert conv is not None
    assert conv.tau is not None
    assert conv.tau < 200
    assert row.trajectory is not None
    assert_allclose(row.trajectory.tau[-1], TAU_REF, rtol=1e-9)


# --- the explanations --------------------------------------------------------------------


def test_explicit_inverse_moves_lsm2_by_the_papers_amount(paper_arithmetic: Table1Result) -> None:
    row = paper_arithmetic.row("LSM(2)")
    paper_dev = row.paper.tau.min - TAU_REF  # -5.497e-3 s
    ours_dev = row.ours.tau.min - TAU_REF
    # Same sign and order of magnitude as the paper's minimum (not its digits: those
    # depend on the order of the floating-point operations).
    assert ours_dev < 0
    assert 0.1 <= ours_dev / paper_dev <= 10.0
    assert 1e-5 < abs(row.ours.tau.mean - TAU_REF) < 1e-3
    # The error grows with the block: the late blocks of a settling step are ill-conditioned.
    tr = row.trajectory
    assert tr is not None
    err = np.abs(tr.tau[tr.valid] - TAU_REF)
    assert err[:5].max() < 1e-6 < err[-5:].max()


@pytest.mark.parametrize("run", MATCHING)
def test_paper_arithmetic_keeps_the_matching_rows_exact(
    paper_arithmetic: Table1Result, run: str
) -> None:
    # The explicit inverse explains LSM(2) without spoiling the rows printed exact.
    assert paper_arithmetic.row(run).digits_match


@pytest.mark.parametrize("run", WLSM_04 + WLSM_46)
def test_frozen_covariance_gives_every_wlsm_row_the_papers_order(
    paper_arithmetic: Table1Result, run: str
) -> None:
    assert paper_arithmetic.row(run).convergence_order_match


@pytest.mark.parametrize("run", ["WLSM(5)", "WLSM(6)"])
def test_frozen_covariance_reproduces_the_slow_rows_statistics(
    paper_arithmetic: Table1Result, run: str
) -> None:
    row = paper_arithmetic.row(run)
    ours = [row.ours.tau.mean, row.ours.tau.max, row.ours.tau.min]
    paper = [row.paper.tau.mean, row.paper.tau.max, row.paper.tau.min]
    # The paper's -1.8 s bias is the tail of a slow convergence, to within 0.1 s.
    assert_allclose(ours, paper, rtol=0, atol=0.1)
    conv = row.ours.converged_at
    assert conv is not None
    assert conv.tau is not None
    assert 10_000 < conv.tau < 30_000


@pytest.mark.parametrize(
    "variant",
    [
        {"precision": "float32"},
        {"decimals": 6},
        {"quantum": DAQ_16BIT_QUANTUM},
        {"noise": 1e-4},
    ],
    ids=["float32", "decimals6", "daq16", "noise"],
)
def test_data_disturbances_do_not_explain_lsm2_or_wlsm4(variant: dict[str, object]) -> None:
    result = reproduce_table1(runs=["LSM(2)", "WLSM(4)"], **variant)  # type: ignore[arg-type]
    lsm2 = result.row("LSM(2)")
    # Each is at least 20 times the paper's LSM(2) error ...
    assert abs(lsm2.ours.tau.min - TAU_REF) > 20 * abs(lsm2.paper.tau.min - TAU_REF)
    # ... and none gives WLSM(4) a smooth convergence in about 1e4 samples.
    wlsm4 = result.row("WLSM(4)")
    conv = wlsm4.ours.converged_at
    assert conv is not None
    smooth_slow = (
        conv.tau is not None and 3_000 < conv.tau < 40_000 and wlsm4.ours.tau.max < TAU_REF
    )
    assert not smooth_slow


def test_frozen_first_update_equals_the_propagated_one() -> None:
    # P starts at pmax·I either way, so the two agree on the first update only.
    t = np.arange(50.0)
    u = parse_signal("square:0:4:0.1").sample(t)
    y = REFERENCE_MODEL.simulate(u)
    frozen = reproduce_table1(runs=["WLSM(1)"], covariance="frozen").row("WLSM(1)").trajectory
    propagated = weighted_least_squares(u, y, 1.0, 0.96, 1e4, PAPER_W0, offset="none")
    assert frozen is not None
    assert_allclose(frozen.W[:2], propagated.W[:2], rtol=1e-12)
    assert not np.allclose(frozen.W[2:10], propagated.W[2:10], rtol=1e-6)


def test_explicit_inverse_estimates_sit_where_the_library_puts_them(
    exact: Table1Result, paper_arithmetic: Table1Result
) -> None:
    for run in ("LSM(2)", "LSM(3)", "MALSM"):
        ours, lib = paper_arithmetic.row(run).trajectory, exact.row(run).trajectory
        assert ours is not None
        assert lib is not None
        np.testing.assert_array_equal(ours.valid, lib.valid)
    lsm3_inv = paper_arithmetic.row("LSM(3)").trajectory
    lsm3 = exact.row("LSM(3)").trajectory
    assert lsm3_inv is not None
    assert lsm3 is not None
    assert_allclose(lsm3_inv.W[lsm3.valid], lsm3.W[lsm3.valid], rtol=1e-9)


def test_noise_is_seeded_and_independent_of_the_rows_run() -> None:
    one = reproduce_table1(runs=["LSM(2)"], noise=1e-3, seed=7).row("LSM(2)")
    two = reproduce_table1(runs=["SRM", "LSM(2)"], noise=1e-3, seed=7).row("LSM(2)")
    other = reproduce_table1(runs=["LSM(2)"], noise=1e-3, seed=8).row("LSM(2)")
    assert one.ours == two.ours
    assert one.ours != other.ours


def test_after_convergence_sets_the_wlsm_run_length() -> None:
    row = reproduce_table1(runs=["WLSM(2)"], after_convergence=500).row("WLSM(2)")
    conv = row.ours.converged_at
    assert conv is not None
    assert conv.K is not None
    assert conv.tau is not None
    assert row.samples == max(conv.K, conv.tau) + 501


# --- definitions, result shape, options -------------------------------------------------


def test_rows_are_the_papers_eleven_in_order() -> None:
    assert [r.run for r in TABLE1_ROWS] == [
        "SRM",
        "LSM(1)",
        "LSM(2)",
        "LSM(3)",
        "MALSM",
        "WLSM(1)",
        "WLSM(2)",
        "WLSM(3)",
        "WLSM(4)",
        "WLSM(5)",
        "WLSM(6)",
    ]
    wlsm = [r for r in TABLE1_ROWS if r.method == "wlsm"]
    assert [(r.gamma, r.pmax) for r in wlsm] == [(0.96, 1e4), (0.7, 1e4), (0.96, 1e3)] * 2
    assert {r.signal for r in wlsm[:3]} == {"square:0:4:0.1"}
    assert {r.signal for r in wlsm[3:]} == {"square:4:6:0.1"}
    for r in TABLE1_ROWS:
        parse_signal(r.signal)  # every input is valid signal syntax


def test_to_dict_has_the_documented_shape(exact: Table1Result) -> None:
    d = json.loads(json.dumps(exact.to_dict(), allow_nan=False))
    assert [r["run"] for r in d["rows"]] == [r.run for r in TABLE1_ROWS]
    for r in d["rows"]:
        for side in (r, r["paper"]):
            assert set(side["K"]) == {"mean", "max", "min"}
            assert set(side["tau"]) == {"mean", "max", "min"}
        wlsm = r["run"].startswith("WLSM")
        for conv in (r["converged_at"], r["paper"]["converged_at"]):
            assert (conv is None) != wlsm
            if wlsm:
                assert set(conv) == {"K", "tau"}
        assert set(r["agreement"]) == {"digits", "convergence_order"}
    lsm2 = next(r for r in d["rows"] if r["run"] == "LSM(2)")
    assert lsm2["paper"]["tau"]["min"] == 250.120736
    assert_allclose(lsm2["deviation"]["tau"]["min"], TAU_REF - 250.120736, atol=1e-6)
    assert d["variant"] == "exact simulation"
    assert d["reference_model"] == {"K": 0.14009, "tau": 250.126233, "dt": 1.0}


def test_format_marks_matches_and_differences(exact: Table1Result) -> None:
    text = exact.format()
    srm = next(line for line in text.splitlines() if line.startswith("SRM"))
    assert "0.140042" in srm
    assert srm.rstrip().endswith("=")
    assert "match to the printed digits: SRM, LSM(1), LSM(3), MALSM;" in text
    assert "WLSM(1), WLSM(2), WLSM(3)" in text
    assert "-0.000000" not in text


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"runs": ["LSM(7)"]}, "unknown run 'LSM(7)'"),
        ({"runs": []}, "at least one row"),
        ({"solver": "qr"}, "solver must be one of lstsq, explicit-inverse"),
        ({"covariance": "none"}, "covariance must be one of propagated, frozen"),
        ({"precision": "float16"}, "precision must be one of float64, float32"),
        ({"decimals": 16}, "decimals must be between 0 and 15"),
        ({"quantum": 0.0}, "quantum must be a finite number of volts > 0"),
        ({"noise": -1.0}, "noise must be a finite standard deviation >= 0"),
        ({"noise": math.nan}, "noise must be a finite standard deviation >= 0"),
        ({"seed": -1}, "seed must be between"),
        ({"after_convergence": 0}, "after_convergence must be between"),
    ],
)
def test_bad_options_are_refused_with_the_reason(options: dict[str, object], message: str) -> None:
    with pytest.raises(InvalidParameterError, match=re.escape(message)):
        Table1Options(**options)  # type: ignore[arg-type]


def test_row_lookup_names_the_rows_run(exact: Table1Result) -> None:
    sub = reproduce_table1(runs=["SRM"])
    with pytest.raises(InvalidParameterError, match="was not run; this result has SRM"):
        sub.row("LSM(1)")


def test_a_record_the_method_refuses_is_reported_in_its_row() -> None:
    # 1 V of noise drowns the 1.4 V step: the SRM refuses it, the table goes on.
    result = reproduce_table1(runs=["SRM", "LSM(1)"], noise=1.0)
    srm = result.row("SRM")
    assert math.isnan(srm.ours.K.mean)
    assert srm.notes[0].startswith("no estimate: the output does not respond to the step")
    assert not srm.digits_match
    assert math.isfinite(result.row("LSM(1)").ours.K.mean)
    line = next(x for x in result.format().splitlines() if x.startswith("SRM"))
    assert line.split()[3:] == ["-", "0.140042", "-", "x"]
    assert result.to_dict()["rows"][0]["K"] == {"mean": None, "max": None, "min": None}
