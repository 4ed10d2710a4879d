"""The paper's Table I through the browser: the three panels on the noise-free twin.

A student logs in to a real lab (``thermolab serve`` with the reference-model
twin at a speed-up of ``TABLE1_SPEEDUP``), runs panel 1 (SRM and LSM on the
step experiment, the step planned at the row's time), panel 2 (MALSM on the
paper's Automatic square wave) and panel 3 (WLSM(1)-(3) settings), each for the
record length ``thermolab reproduce table1`` uses, then compares the runs.
Every figure on the page must print the digits of the library's reproduction
(:func:`thermolab.reproduction.reproduce_table1`, called here), six decimals
as the paper prints them; the samples to converge must be the same counts.

Each row runs on a twin of its own: the paper's simulated records start from
rest at 0 V, and a twin heated by the run before takes about 40 time
constants (10 000 s) to be at rest to the printed digits.

The paper-practical twin (noise, quantisation, jitter) gives Table II's
scatter instead, and the page must say why and never show it as final.
"""

from __future__ import annotations

import json
import os
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from thermolab.reproduction import RowResult, reproduce_table1

pytestmark = pytest.mark.browser

# The speed-up a teacher gives twins in the lab's file (``speedup = ...``, here
# ``--speedup``): a 2000-sample run at T = 1 s takes about two seconds.
TABLE1_SPEEDUP = 1000.0

ROWS = ("SRM", "LSM(1)", "MALSM", "WLSM(1)", "WLSM(2)", "WLSM(3)")
# Rig per row that takes one (SRM and LSM(1) are one run of panel 1).
RIGS = {"SRM": "t1-step", "MALSM": "t1-malsm", "WLSM(1)": "t1-w1", "WLSM(2)": "t1-w2",
        "WLSM(3)": "t1-w3", "practical": "t1-practical",
        "practical-2": "t1-practical-2"}  # fmt: skip

CONFIG = 'title = "Table I through the browser"\n' + "".join(
    f'\n[[rigs]]\nid = "{rig}"\ntitle = "Twin {rig}"\n'
    f'spec = "{"sim:paper-practical" if name.startswith("practical") else "sim"}"\n'
    for name, rig in RIGS.items()
)

ROLE = "[data-testid=access-role]"
# Where the Table I test writes the figures it read off the page (for the benchmark).
FIGURES_FILE = "THERMOLAB_TABLE1_FIGURES"


@pytest.fixture(scope="module")
def table1() -> dict[str, RowResult]:
    """The library's reproduction of the rows the three panels run."""
    result = reproduce_table1(runs=list(ROWS))
    return {row.run: row for row in result.rows}


@pytest.fixture(scope="module")
def fast_lab(tmp_path_factory: pytest.TempPathFactory, start_lab: Any) -> Iterator[Any]:
    """A lab whose twins run TABLE1_SPEEDUP times faster than real time."""
    with start_lab(
        tmp_path_factory.mktemp("table1"),
        {"paula": "student"},
        config=CONFIG,
        speedup=TABLE1_SPEEDUP,
    ) as server:
        yield server


@pytest.fixture
def student(context_for: Any, fast_lab: Any) -> Iterator[Any]:
    context = context_for(fast_lab, "paula", viewport={"width": 1280, "height": 900})
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.errors = errors
    try:
        yield page
    finally:
        context.close()


def printed(value: float) -> str:
    """A figure as the paper's Table I prints it (and the page must show it)."""
    return f"{value:.6f}"


def printed_stats(stats: Any) -> str:
    """Mean / max / min as the paper prints them."""
    return " / ".join(printed(v) for v in (stats.mean, stats.max, stats.min))


def spread(text: str) -> str:
    """A cell's mean / max / min (a single value stands for all three, as the page shows it)."""
    parts = text.split(" / ")
    return " / ".join(parts * 3 if len(parts) == 1 else parts)


def take_control(page: Any, lab: Any, rig: str) -> None:
    page.goto(f"{lab.url}/#/rig/{rig}")
    page.wait_for_function("sel => document.querySelector(sel)?.dataset.role", arg=ROLE)
    page.click("button[data-action=ask]")
    page.wait_for_function("sel => document.querySelector(sel)?.dataset.role === 'controller'",
                           arg=ROLE)  # fmt: skip


def release(page: Any) -> None:
    page.click("button[data-action=release]")
    page.wait_for_function("sel => document.querySelector(sel)?.dataset.role === 'watcher'",
                           arg=ROLE)  # fmt: skip


def run_panel(page: Any, panel: str, fields: dict[str, str], *, automatic: bool,
              planned: bool = False) -> float:  # fmt: skip
    """Fill a panel's form, START, wait until the run has finished; the wall time taken."""
    page.click(f"[role=tab][data-panel={panel}]")
    form = f"[data-panel-form={panel}]"
    page.set_checked(f"{form} input[name=automatic]", automatic)
    if not automatic:
        page.set_checked(f"{form} input[name=planned]", planned)
    for name, value in fields.items():
        page.fill(f"#{panel}-{name}", value)
    started = time.monotonic()
    page.click(f"[data-panel-view={panel}] button[data-action=start]")
    status = f"[data-testid=run-status-{panel}]"
    page.wait_for_selector(f"{status}:text('finished')", timeout=120_000)
    return time.monotonic() - started


def cell(page: Any, row: str, field: str) -> str:
    return str(page.inner_text(f"{row} [data-field={field}]")).strip()


def figure(text: str) -> str:
    """The figure of a cell, without the notes under it (SRM's last-sample gain)."""
    return text.splitlines()[0].strip()


def test_the_three_panels_on_the_twin_give_table_one(
    student: Any, fast_lab: Any, table1: dict[str, RowResult], artifacts: Path
) -> None:
    page = student
    walls: dict[str, float] = {}
    srm, lsm = table1["SRM"], table1["LSM(1)"]
    low, high, at = re.fullmatch(r"step:([-\d.]+):([-\d.]+)@([\d.]+)", srm.row.signal).groups()

    # Panel 1: the step planned at the row's time (at a speed-up of 1000 a change
    # of set point made by hand lands on a sample nobody can choose).
    take_control(page, fast_lab, RIGS["SRM"])
    # A step planned after the run's end is refused before anything is sent.
    sent: list[str] = []
    page.on("request", lambda r: sent.append(r.url) if r.url.endswith("/runs") else None)
    page.set_checked("[data-panel-form=srm-lsm] input[name=planned]", True)
    page.fill("#srm-lsm-n", str(srm.samples))
    page.fill("#srm-lsm-stepAt", str(srm.samples))
    page.click("[data-panel-view=srm-lsm] button[data-action=start]")
    error = f"The step must come before the run ends ({srm.samples} s)."
    assert page.inner_text("#srm-lsm-stepAt-err") == error
    assert page.evaluate("() => document.activeElement.id") == "srm-lsm-stepAt"
    assert sent == []
    walls["SRM, LSM(1)"] = run_panel(
        page, "srm-lsm",
        {"dt": "1", "n": str(srm.samples), "setpoint": low, "stepTo": high, "stepAt": at},
        automatic=False, planned=True,
    )  # fmt: skip
    results = "[data-testid=results-srm-lsm]"
    for method in ("srm", "lsm"):
        page.wait_for_selector(
            f"{results} [data-method={method}] [data-field=status]:text('final')"
        )
    srm_row, lsm_row = f"{results} [data-method=srm]", f"{results} [data-method=lsm]"
    # SRM: Ts at 63.2 %, the settled gain, and the paper's figure, the last sample's gain.
    assert cell(page, srm_row, "tau") == printed(srm.ours.tau.mean)
    assert cell(page, srm_row, "Klast") == f"last sample: {printed(srm.ours.K.mean)}"
    assert figure(cell(page, srm_row, "K")) == printed(srm.detail.K)
    assert cell(page, lsm_row, "K") == printed(lsm.ours.K.mean)
    assert cell(page, lsm_row, "tau") == printed(lsm.ours.tau.mean)
    for row in (srm_row, lsm_row):
        assert cell(page, row, "theta") == printed(0.0)  # eq. 4 has no dead time
    page.locator(".panels").screenshot(path=str(artifacts / "table1-panel-1.png"))
    release(page)

    # Panel 2: MALSM on the Automatic square wave (a tenth of the sampling frequency).
    malsm = table1["MALSM"]
    lo, hi, hz = malsm.row.signal.split(":")[1:]
    assert float(hz) == 0.1  # what the panel's Automatic option makes of T = 1 s
    take_control(page, fast_lab, RIGS["MALSM"])
    walls["MALSM"] = run_panel(
        page, "malsm",
        {"dt": "1", "n": str(malsm.samples), "window": str(malsm.row.window),
         "low": lo, "high": hi},
        automatic=True,
    )  # fmt: skip
    release(page)

    # Panel 3: WLSM with the paper's settings (1)-(3), each as long as the
    # reproduction's run: 2000 samples after convergence.
    for run in ("WLSM(1)", "WLSM(2)", "WLSM(3)"):
        row = table1[run]
        lo, hi, _ = row.row.signal.split(":")[1:]
        take_control(page, fast_lab, RIGS[run])
        walls[run] = run_panel(
            page, "wlsm",
            {"dt": "1", "n": str(row.samples), "gamma": str(row.row.gamma),
             "pmax": str(row.row.pmax), "a0": str(row.row.w0[0]),
             "b0": str(row.row.w0[1]), "low": lo, "high": hi},
            automatic=True,
        )  # fmt: skip
        release(page)

    # The comparison page, as in the paper's Table I: every run beside the reference.
    page.goto(f"{fast_lab.url}/#/runs")
    page.wait_for_selector("table.runs tbody tr")
    boxes = page.locator("table.runs tbody input[name=run]")
    assert boxes.count() == 5
    for i in range(5):
        boxes.nth(i).check()
    page.click("button:text('Compare the chosen runs')")
    page.wait_for_selector("table.compare tbody tr[data-method=wlsm] >> nth=2")
    shown = page.evaluate(
        """() => [...document.querySelectorAll('table.compare tbody tr')].map((tr) => ({
             run: +tr.dataset.run, method: tr.dataset.method,
             K: tr.querySelector('[data-field=K]').firstChild.textContent,
             Klast: tr.querySelector('[data-field=Klast]')?.textContent ?? null,
             tau: tr.querySelector('[data-field=tau]').textContent,
             theta: tr.querySelector('[data-field=theta]').textContent,
             conv: tr.querySelector('[data-field=conv]').textContent }))"""
    )
    page.screenshot(path=str(artifacts / "table1-compare.png"), full_page=True)
    # Runs are listed newest first; the page's rows follow the order of the ids chosen.
    by_run: dict[str, dict[str, Any]] = {}
    wlsm_rows = sorted((r for r in shown if r["method"] == "wlsm"), key=lambda r: r["run"])
    for name, r in zip(("WLSM(1)", "WLSM(2)", "WLSM(3)"), wlsm_rows, strict=True):
        by_run[name] = r
    by_run.update({"SRM": _one(shown, "srm"), "LSM(1)": _one(shown, "lsm"),
                   "MALSM": _one(shown, "malsm")})  # fmt: skip
    mismatches = []
    for name in ROWS:
        ours, page_row = table1[name].ours, by_run[name]
        want_k = (
            printed_stats(type(ours.K).single(table1[name].detail.K))
            if name == "SRM"
            else printed_stats(ours.K)
        )
        expected = {"K": want_k, "tau": printed_stats(ours.tau), "theta": printed(0.0)}
        page_row = {**page_row, "K": spread(page_row["K"]), "tau": spread(page_row["tau"])}
        if name == "SRM":
            expected["Klast"] = f"last sample: {printed(ours.K.mean)}"
        if ours.converged_at is not None:
            # The lab counts convergence on the run itself (±1 % of the mean of its
            # last 2000 samples); the reproduction on a pilot record twice as long,
            # whose stabilisation value is the converged one. The run ends 2000
            # samples after convergence, so its mean still holds the tail of the
            # approach: the counts may differ by a sample (WLSM(3)'s Ks: 122 and
            # 123). The page must show the count of the reproduction's own run
            # trajectory counted as the lab counts, and be within a sample of the row.
            trajectory = table1[name].trajectory
            assert trajectory is not None
            conv = trajectory.converged_at(last=2000)
            for param in ("K", "tau"):
                assert abs(conv[param] - getattr(ours.converged_at, param)) <= 1
            expected["conv"] = f"{conv['K']} / {conv['tau']}"
        for key, want in expected.items():
            if page_row[key] != want:
                mismatches.append(f"{name} {key}: page {page_row[key]!r}, library {want!r}")
    assert mismatches == [], "\n".join(mismatches)
    # The JSON export carries θ beside Ks and Ts for every method (the CSV holds samples).
    thetas = page.evaluate(
        """async (ids) => Promise.all(ids.map(async (id) => {
             const r = await (await fetch(`/api/runs/${id}/export.json`)).json();
             return Object.values(r.run.results).map((m) => m.latest.extras.theta); }))""",
        sorted({r["run"] for r in shown}),
    )
    assert [theta for run in thetas for theta in run] == [0.0] * 6
    print("\nTable I through the browser at speed-up", TABLE1_SPEEDUP, "wall s:",
          {k: round(v, 2) for k, v in walls.items()})  # fmt: skip
    if out := os.environ.get(FIGURES_FILE):
        # benchmarks/bench_table1_browser.py prints these beside the command line's.
        figures = {"speedup": TABLE1_SPEEDUP, "walls": walls, "page": by_run,
                   "samples": {name: table1[name].samples for name in ROWS}}  # fmt: skip
        Path(out).write_text(json.dumps(figures), encoding="utf-8")
    assert page.errors == []


def _one(rows: list[dict[str, Any]], method: str) -> dict[str, Any]:
    found = [r for r in rows if r["method"] == method]
    assert len(found) == 1, (method, rows)
    return found[0]


def test_the_paper_practical_twin_scatters_and_the_page_says_why(
    student: Any, fast_lab: Any, table1: dict[str, RowResult], artifacts: Path
) -> None:
    """Table II's lesson: with noise, quantisation and jitter, short windows scatter (the
    page says why and never shows them as final) and the equation-error fit's residuals
    are not white (a note: the whole-record verdict trusts a model that is right)."""
    page = student
    # Panel 2: MALSM's 100-sample windows scatter (the paper's Ts 224-597 s).
    malsm = table1["MALSM"]
    lo, hi, _ = malsm.row.signal.split(":")[1:]
    take_control(page, fast_lab, RIGS["practical"])
    run_panel(
        page,
        "malsm",
        {
            "dt": "1",
            "n": str(malsm.samples),
            "window": str(malsm.row.window),
            "low": lo,
            "high": hi,
        },
        automatic=True,
    )
    row = "[data-testid=results-malsm] [data-method=malsm]"
    # The run's end and its judgement: seconds on an idle machine, past 30 s on a busy one.
    page.wait_for_selector(f"{row}[data-trusted=false]", timeout=90_000)
    assert cell(page, row, "status") == "not trusted: see the warnings"
    warning = "[data-testid=results-malsm] [data-testid=estimate-warnings] li[data-method=malsm]"
    assert "did not converge" in page.inner_text(warning)
    assert "Table II" in page.inner_text(warning)
    page.locator(".panels").screenshot(path=str(artifacts / "practical-panel-2.png"))
    release(page)

    # Panel 1 on a cold practical twin: LSM's residuals are not white (noise), which no
    # real kit's record passes either; judged as a whole record (issue #21: it follows
    # the record and agrees with the output-error fit), the model is trusted, and the
    # residual test is listed as a note, saying to compare with OE.
    # The step comes after 50 s at rest, not at the row's first second: on a noisy record a
    # step at once leaves the operating point and the dead time to the noise, and the verdict
    # rightly says so ("operating point undetermined", "dead time uncertain") on 12 of 300
    # seeds of the practical twin; with 50 s before it, on none of 300.
    srm = table1["SRM"]
    low, high, _ = re.fullmatch(r"step:([-\d.]+):([-\d.]+)@([\d.]+)", srm.row.signal).groups()
    at = "50"
    take_control(page, fast_lab, RIGS["practical-2"])
    run_panel(
        page,
        "srm-lsm",
        {"dt": "1", "n": str(srm.samples), "setpoint": low, "stepTo": high, "stepAt": at},
        automatic=False,
        planned=True,
    )
    lsm_row = "[data-testid=results-srm-lsm] [data-method=lsm]"
    page.wait_for_selector(f"{lsm_row}[data-trusted=true]")
    warnings = " ".join(
        page.locator(
            "[data-testid=results-srm-lsm] [data-testid=estimate-warnings] li[data-method=lsm]"
        ).all_inner_texts()
    )
    assert "residual test failed" in warnings
    assert "measurement noise" in warnings
    page.locator(".panels").screenshot(path=str(artifacts / "practical-panel-1.png"))
    release(page)

    # The run's page shows the scatter (mean / max / min) and why none of it is final.
    page.goto(f"{fast_lab.url}/#/runs")
    page.wait_for_selector("table.runs tbody tr")
    malsm_run = page.get_attribute(
        f"table.runs tbody tr:has(td:text-is('{RIGS['practical']}'))", "data-run"
    )
    page.goto(f"{fast_lab.url}/#/runs/{malsm_run}")
    result = "tr[data-method=malsm]"
    page.wait_for_selector(f"{result}[data-trusted=false]")
    _, high_k, low_k = (float(v) for v in cell(page, result, "Kstats").split(" / "))
    assert high_k > 1.1 * low_k  # Table II's scatter, shown as it is
    assert "did not converge" in page.inner_text(result)
    assert "never" in cell(page, result, "conv")
    page.screenshot(path=str(artifacts / "practical-run.png"), full_page=True)
    assert page.errors == []
