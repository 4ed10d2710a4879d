"""The figures a page prints and the planned step of panel 1, module by module in Chromium."""

from __future__ import annotations

from typing import Any

import pytest

pytestmark = pytest.mark.browser


def run_js(page: Any, body: str) -> Any:
    return page.evaluate(f"async () => {{ {body} }}")


def test_figures_print_the_papers_six_decimals(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { fmtFigure } = await import('/js/model.js');
        const i18n = await import('/js/i18n.js');
        const en = [fmtFigure(250.126233), fmtFigure(0.1400424361), fmtFigure(0), fmtFigure(-3.5),
                    fmtFigure(1e-6), fmtFigure(2.5e7), fmtFigure(NaN), fmtFigure(null)];
        await i18n.useLanguage('pt-BR');
        const pt = fmtFigure(250.126233);
        await i18n.useLanguage('en');
        return { en, pt };
        """,
    )
    assert r["en"] == [
        "250.126233",
        "0.140042",
        "0.000000",
        "-3.500000",
        "0.000001",
        "25000000",
        "–",
        "–",
    ]
    assert r["pt"] == "250,126233"


def test_a_planned_step_is_sent_as_a_step_signal(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { buildRunSpec, isPlannedStep, plannedStepSignal } = await import('/js/runspec.js');
        const panel = { id: 'srm-lsm' };
        const planned = buildRunSpec(panel, { dt: 1, n: 2000, setpoint: 0, stepTo: 10, stepAt: 1 },
                                     false, { offset: true });
        const byHand = buildRunSpec(panel, { dt: 1, n: 2000, setpoint: 3 }, false);
        return { planned, byHand, sig: plannedStepSignal(-2.5, 7, 0.5),
                 is: ['step:0:10@1', 'square:4:6:0.1', null].map((signal) =>
                       isPlannedStep({ signal })) };
        """,
    )
    assert r["planned"]["signal"] == "step:0:10@1"
    assert "setpoint" not in r["planned"]
    assert r["planned"]["methods"] == ["srm", "lsm"]
    assert r["byHand"] == {"dt": 1, "samples": 2000, "setpoint": 3, "methods": ["srm", "lsm"]}
    assert r["sig"] == "step:-2.5:7@0.5"
    assert r["is"] == [True, False, False]


def test_a_run_that_never_converged_is_not_trusted_and_says_why(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { readRun } = await import('/js/runspec.js');
        const { readResult } = await import('/js/results.js');
        const { renderResults } = await import('/js/views/panels/results.js');
        const latest = { K: 0.1359, tau: 226.4, k: 1999, valid: true, final: true,
                         extras: { warnings: [], trusted: true, theta: 0 } };
        const scatter = { latest, stats: { K: { mean: 0.14, max: 0.27, min: 0.09 },
                          tau: { mean: 265, max: 695, min: 164 },
                          converged_at: { K: null, tau: 1999 }, converged: false } };
        const settled = { ...scatter, stats: { ...scatter.stats, converged: true } };
        const old = { ...scatter, stats: { ...scatter.stats, converged: undefined } };
        const run = readRun({ id: 9, status: 'finished', dt: 1, samples: 2000, methods: ['malsm'],
                              results: { malsm: scatter } });
        const view = { def: { title: 'Panel 2', methods: ['malsm'] },
                       results: document.createElement('div'),
                       operatingPoint: document.createElement('p') };
        renderResults(view, run);
        const row = view.results.querySelector('tr[data-method=malsm]');
        return {
          status: row.querySelector('[data-field=status]').textContent,
          theta: row.querySelector('[data-field=theta]').textContent,
          trusted: row.dataset.trusted,
          warning: view.results.querySelector('li[data-kind=not-converged]')?.textContent ?? null,
          results: [scatter, settled, old].map((s) => {
            const f = readResult(s, 'malsm');
            return [f.converged, f.trusted, f.final.theta];
          }),
        };
        """,
    )
    assert r["status"] == "not trusted: see the warnings"
    assert r["trusted"] == "false"
    assert r["theta"] == "0.000000"
    assert r["warning"].startswith("Moving-window LS (MALSM): did not converge.")
    # The server's verdict decides; runs stored before it judged keep their trust.
    assert r["results"] == [[False, False, 0], [True, True, 0], [True, True, 0]]


def test_the_model_drawn_over_the_data_has_its_dead_time(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { predict } = await import('/js/model.js');
        const u = [10, 10, 10, 10, 10];
        const b = 1 - Math.exp(-1);
        return { b, none: Array.from(predict(u, 0, { K: 1, tau: 1 }, 1)),
                 late: Array.from(predict(u, 0, { K: 1, tau: 1, theta: 2 }, 1)),
                 warm: Array.from(predict(u, 0, { K: 1, tau: 1, theta: 2 }, 1, undefined, 10)) };
        """,
    )
    b = r["b"]
    assert r["none"][:2] == [0, pytest.approx(10 * b)]
    # θ = 2 s at dt = 1 s: the input reaches the output two samples later (off before START).
    assert r["late"][:4] == [0, 0, 0, pytest.approx(10 * b)]
    # A record that starts settled at 10 (K = 1): the input before it was on, so it stays.
    assert r["warm"] == pytest.approx([10] * 5)
