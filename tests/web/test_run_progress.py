"""The rig page's run progress: an accessible bar with the time left and the planned end."""

from __future__ import annotations

from typing import Any

import pytest

pytestmark = pytest.mark.browser


def run_js(page: Any, body: str) -> Any:
    return page.evaluate(f"async () => {{ {body} }}")


def test_progress_counts_samples_and_the_time_left_to_the_planned_end(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { runProgress } = await import('/js/views/panels/results.js');
        const start = Date.parse('2026-01-01T10:00:00Z');
        const run = { nSamples: 2000, dt: 1, endsAt: '2026-01-01T10:33:20+00:00' };
        const at = runProgress(run, 500, start + 500e3);
        // A twin at a speed-up: its planned end is sooner than samples × dt.
        const fast = runProgress({ ...run, endsAt: '2026-01-01T10:00:20Z' }, 1000, start + 10e3);
        const old = runProgress({ nSamples: 100, dt: 2, endsAt: null }, 40, start);
        const open = runProgress({ nSamples: null, dt: 1 }, 3, start);
        return { at: [at.taken, at.samples, at.secondsLeft, at.end.toISOString()],
                 fast: fast.secondsLeft, old: old.secondsLeft, open };
        """,
    )
    assert r["at"] == [500, 2000, 1500, "2026-01-01T10:33:20.000Z"]
    assert r["fast"] == 10
    assert r["old"] == 120  # no planned end stored: (samples left) × dt
    assert r["open"] is None


def test_the_progress_bar_is_a_progressbar_with_its_values(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { renderProgress } = await import('/js/views/panels/results.js');
        const parent = document.createElement('div');
        const results = document.createElement('div');
        parent.append(results);
        document.body.append(parent);
        const view = { results };
        const ends = new Date(Date.now() + 1500e3).toISOString();
        const run = { status: 'running', nSamples: 2000, dt: 1, endsAt: ends };
        renderProgress(view, run, 500);
        const bar = parent.querySelector('[data-testid=run-progress]');
        const shown = { role: bar.getAttribute('role') ?? bar.tagName,
                        max: bar.max, value: bar.value,
                        valuetext: bar.getAttribute('aria-valuetext'),
                        text: parent.querySelector('[data-testid=run-progress-text]').textContent,
                        hidden: view.progress.el.hidden };
        renderProgress(view, { ...run, status: 'finished' }, 2000);
        return { shown, hiddenAfter: view.progress.el.hidden };
        """,
    )
    shown = r["shown"]
    assert shown["role"] == "PROGRESS"  # a native <progress>: role progressbar, values exposed
    assert (shown["max"], shown["value"], shown["hidden"]) == (2000, 500, False)
    assert shown["valuetext"].startswith("Sample 500 of 2000: 25 minutes left, ends at ")
    assert shown["text"].startswith("Sample 500 of 2000: 25:00 left, ends at ")
    assert r["hiddenAfter"] is True


def test_untrusted_results_never_look_final_and_every_warning_is_listed(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { renderResults, timingText } = await import('/js/views/panels/results.js');
        const { readRun } = await import('/js/runspec.js');
        const flagged = { K: 0.0028, tau: 3.1, k: 1999, valid: true, final: true,
                          extras: { warnings: ['not settled: the output still moves; run longer'],
                                    trusted: false } };
        const clean = { K: 0.14, tau: 250, k: 1999, valid: true, final: true, extras: {} };
        const run = readRun({ id: 4, status: 'finished', dt: 1, samples: 2000,
                              methods: ['srm', 'lsm'], results: { srm: { latest: flagged },
                              lsm: { latest: clean } },
                              timing: { rig: 'real', maxLateness: 0.25, p95Lateness: 0.1,
                                        periodSpread: 0.08, warnings: ['timing jitter: ...'] } });
        const view = { def: { title: 'Panel 1', methods: ['srm', 'lsm'] },
                       results: document.createElement('div'),
                       operatingPoint: document.createElement('p') };
        renderResults(view, run);
        const row = (m) => view.results.querySelector(`tr[data-method=${m}]`);
        const status = (m) => row(m).querySelector('[data-field=status]').textContent;
        const items = [...view.results.querySelectorAll('[data-testid=estimate-warnings] li')];
        return { srm: [status('srm'), row('srm').dataset.trusted, row('srm').className],
                 lsm: [status('lsm'), row('lsm').dataset.trusted],
                 items: items.map((li) => li.textContent),
                 twin: timingText({ rig: 'twin' }), real: timingText(run.timing) };
        """,
    )
    assert r["srm"] == ["not trusted: see the warnings", "false", "not-trusted"]
    assert r["lsm"] == ["final (at END)", "true"]
    assert len(r["items"]) == 2
    # The run's timing concerns every method; each warning says what to do (ident.advice).
    assert r["items"][0].startswith("timing jitter: samples were not evenly spaced")
    assert r["items"][0].endswith(" (...)")
    assert r["items"][1].endswith(
        ": not settled: the record ends before the output settles, so K and tau are "
        "extrapolated; record at least four time constants after the step "
        "(the output still moves; run longer)"
    )
    assert r["twin"].startswith("exact: the twin advances by dt per sample")
    assert r["real"].startswith("samples read up to 0.25 s late (95 % within 0.1 s)")


def test_each_method_says_the_operating_point_it_used_and_found(module_page: Any) -> None:
    r = run_js(
        module_page,
        """
        const { renderResults } = await import('/js/views/panels/results.js');
        const { readRun } = await import('/js/runspec.js');
        const { predictionBase } = await import('/js/model.js');
        const op = { handling: 'fit', start: 'settled', ambient: 0.25,
                     reason: 'the record starts settled under 5 V' };
        const latest = { K: 0.14, tau: 250, k: 999, valid: true, final: true,
                         W: [0.9, 0.014, 0.025], extras: { operating_point: op } };
        const run = readRun({ id: 5, status: 'finished', dt: 1, samples: 1000, methods: ['lsm'],
                              results: { lsm: { latest } },
                              operatingPoint: { asked: 'auto', used: 'auto',
                                                reason: 'auto: each method decides' } });
        const view = { def: { title: 'Panel 1', methods: ['srm', 'lsm'], optional: ['srm'] },
                       results: document.createElement('div'),
                       operatingPoint: document.createElement('p') };
        renderResults(view, run);
        return { text: view.operatingPoint.textContent,
                 base: predictionBase('auto', latest.W, 3.0),
                 initial: predictionBase('auto', [0.9, 0.014], 3.0) };
        """,
    )
    assert r["text"].startswith("Operating point: auto: each method decides")
    assert "Least squares" in r["text"] or "LSM" in r["text"]
    assert ": fit, ambient 0.25 (the record starts settled under 5 V)." in r["text"]
    assert abs(r["base"] - 0.25) < 1e-12  # c / (1 - a): the method fitted the constant term
    assert r["initial"] == 3.0  # no constant term: the first output is the base
