// @ts-check
// One run: what was asked, its charts (output with the model, input, and the
// convergence of the recursive methods), every method's results, the CSV.

import { api, spreadsheetUrl } from "../api.js";
import { Chart, TIME_WINDOWS } from "../charts.js";
import { h, setText, when } from "../dom.js";
import { fmt, fmtFigure, predict, predictionBase } from "../model.js";
import { readResult } from "../results.js";
import { inputText, methodTitle, readRun, runPair, runStatusText } from "../runspec.js";
import { kitPair, pairEnd, pairLabel } from "../channelwords.js";
import { settingsText, statusParts } from "../runwords.js";
import { identReason, identWarning } from "../identwords.js";
import { lastSampleGain, operatingPointHow, timingText } from "./panels/results.js";
import { t } from "../i18n.js";
import { personName } from "../shapes.js";

/**
 * Why a method has no model, and its warnings: the server's sentences, "–" when none.
 * @param {{valid: boolean, trusted?: boolean, converged: boolean, reason?: string | null, warnings: string[]}} f
 * @returns {Array<Node | string>}
 */
function reasonCell(f) {
  const status = f.valid ? (f.trusted === false ? t("estimate.notTrusted") : null) : f.reason ? identReason(f.reason) : t("estimate.noModel");
  const notes = [status, f.converged ? null : t("run.notConverged"), ...f.warnings.map(identWarning)];
  const shown = /** @type {Array<Node | string>} */ (notes.filter((n) => n !== null && n !== ""));
  return shown.length ? shown.flatMap((n, i) => (i ? ["; ", n] : [n])) : ["–"];
}

/** At most this many points per chart: longer runs are drawn decimated. */
const MAX_POINTS = 4000;

/**
 * A run's figures per method: the stored results once the run has ended,
 * else the latest estimates of the running run.
 * @param {any} exported  GET /api/runs/{run}/export.json
 */
export function runFigures(exported) {
  const run = readRun(exported.run);
  if (!run) throw new TypeError("export.json without a run");
  const stored = exported.methods && typeof exported.methods === "object" ? exported.methods : {};
  const found = Object.keys(stored).length ? Object.keys(stored) : Object.keys(run.results);
  // In the order the run asked for them (the paper's order), then any other.
  const order = (m) => (run.methods.indexOf(m) + 1 || 99);
  const labels = found.sort((a, b) => order(a) - order(b));
  return {
    run,
    figures: labels.map((label) => {
      const entry = stored[label];
      return { label, ...readResult(entry ? entry.result : run.results[label], entry?.method ?? label) };
    }),
  };
}

export function mount(main, { params }, ctx) {
  const id = params[0];
  ctx.setTitle(t("runs.label", { run: id }));
  const status = h("p", { class: "muted", role: "status" }, t("app.loading"));
  main.append(h("p", { class: "crumbs" }, h("a", { href: "#/runs" }, t("nav.runs")), t("run.crumb", { run: id })), h("h1", null, t("runs.label", { run: id })), status);
  const abort = new AbortController();
  const charts = [];
  (async () => {
    let exported;
    try {
      exported = await api.exportRun(id, { signal: abort.signal });
    } catch (err) {
      if (err.name !== "AbortError") setText(status, t("run.failed", { run: id, error: err.message }));
      return;
    }
    setText(status, "");
    render(main, exported, charts);
  })();
  return () => {
    abort.abort();
    for (const c of charts) c.destroy();
  };
}

function render(main, exported, charts) {
  const { run, figures } = runFigures(exported);
  const facts = h("dl", { class: "facts" });
  const add = (k, v) => facts.append(h("dt", null, k), h("dd", null, v));
  add(t("runs.rig"), run.rig ?? "–");
  if (run.user) add(t("runs.student"), personName(run.user, run.userName, true));
  add(t("runs.status"), statusParts(run, runStatusText));
  add(t("runs.started"), when(run.startedAt));
  add(t("run.endedAt"), when(run.endedAt));
  add(t("run.dt"), t("run.seconds", { seconds: run.dt }));
  add(t("runs.samples"), run.nSamples ? t("run.samplesOf", { samples: run.samples, of: run.nSamples }) : String(run.samples));
  add(t("runs.input"), inputText(run));
  add(t("runs.methods"), run.methods.map(methodTitle).join(", "));
  // The pair identified, where it is not u -> y (a kit's heater 2 -> sensor 2).
  const pair = runPair(run);
  const paired = pair.input !== "u" || pair.output !== "y";
  if (paired) add(t("panel.pair"), pairLabel(pair.input, pair.output));
  const settings = settingsText(run.settings ?? {});
  if (settings.length) add(t("run.settings"), settings.join("; "));
  const w0 = run.settings?.w0;
  if (Array.isArray(w0)) add(t("run.w0"), `[${w0.map((v) => fmt(v)).join(", ")}]`);
  if (run.operatingPoint?.used !== null && run.operatingPoint?.used !== undefined) {
    facts.append(h("dt", null, t("panel.operatingPoint")), h("dd", { "data-testid": "operating-point" }, operatingPointHow(run.operatingPoint)));
  }
  if (run.timing) {
    facts.append(h("dt", null, t("run.timing")), h("dd", { "data-testid": "timing" }, [timingText(run.timing), ...(run.timing.warnings ?? []).flatMap((w) => [" ", identWarning(w)])]));
  }
  main.append(
    h(
      "section",
      { class: "card" },
      h("h2", null, t("run.heading")),
      facts,
      h(
        "div",
        { class: "buttons" },
        h("a", { class: "button primary", href: api.csvUrl(run.id), download: `run-${run.id}.csv`, "data-testid": "csv-link" }, t("run.csv")),
        h("a", { class: "button", href: spreadsheetUrl(api.csvUrl(run.id)), download: `run-${run.id}.csv`, "data-testid": "csv-sheet-link" }, t("csv.spreadsheet")),
        h("a", { class: "button", href: api.exportUrl(run.id), download: `run-${run.id}.json` }, t("run.json")),
      ),
    ),
  );
  main.append(resultsSection(figures));

  const samples = exported.samples ?? {};
  const time = Float64Array.from(samples.t ?? []);
  // The charts and the model are of the pair identified (its columns are in the record).
  const u = Float64Array.from(samples[pair.input] ?? samples.u ?? []);
  const y = Float64Array.from(samples[pair.output] ?? samples.y ?? []);
  const chartBox = h("section", { class: "card", "aria-labelledby": "run-charts" }, h("h2", { id: "run-charts" }, t("run.charts")));
  const modelPick = h("select", { id: "run-model" });
  const withModel = figures.filter((f) => f.valid && f.final.K !== null && (f.final.tau ?? 0) > 0);
  modelPick.append(h("option", { value: "" }, t("charts.noModel")), ...withModel.map((f, i) => h("option", { value: String(i) }, methodTitle(f.method))));
  const lsm = withModel.findIndex((f) => f.method === "lsm");
  if (withModel.length) modelPick.value = String(lsm >= 0 ? lsm : 0);
  chartBox.append(h("div", { class: "field inline" }, h("label", { for: "run-model" }, t("charts.overlay")), modelPick));
  main.append(chartBox);
  const yhat = new Float64Array(y.length).fill(Number.NaN);
  const computeModel = () => {
    const f = modelPick.value === "" ? null : withModel[Number(modelPick.value)];
    if (!f || y.length === 0) yhat.fill(Number.NaN);
    else {
      const base = predictionBase(run.operatingPoint?.used, f.final.W, y[0]);
      predict(u, base, { K: f.final.K ?? Number.NaN, tau: f.final.tau ?? Number.NaN, theta: f.final.theta ?? 0 }, run.dt, yhat, y[0] - base);
    }
  };
  computeModel();
  const thin = thinner(time.length);
  const out = new Chart(chartBox, {
    label: t("run.outputChart", { run: run.id }),
    xLabel: t("axis.time"),
    yLabel: t("run.outputAxis"),
    series: [{ label: paired ? pairEnd(pair.output, kitPair(pair.input, pair.output)) : t("axis.output") }, { label: t("series.model"), dash: [6, 4], color: "#D55E00", width: 2, auto: false }],
    source: () => [thin(time), thin(y), thin(yhat)],
    // A long square wave is a solid block at full width: its last periods on request,
    // the input chart showing the same time.
    windows: TIME_WINDOWS,
    onWindow: (seconds) => inp.setWindow(seconds),
  });
  const inp = new Chart(chartBox, {
    label: t("run.inputChart", { run: run.id }),
    xLabel: t("axis.time"),
    yLabel: t("run.inputAxis"),
    height: 160,
    series: [{ label: paired ? pairEnd(pair.input, kitPair(pair.input, pair.output)) : t("axis.input"), color: "#009E73" }],
    source: () => [thin(time), thin(u)],
  });
  charts.push(out, inp);
  modelPick.addEventListener("change", () => {
    computeModel();
    out.invalidate();
  });

  for (const f of figures) {
    const tr = f.trajectory;
    if (!tr) continue;
    // Only estimates with a first-order meaning are drawn (uPlot has no NaN gaps).
    const keep = tr.k.map((_, i) => Number.isFinite(tr.K[i]) && Number.isFinite(tr.tau[i]));
    const pick = (a) => Float64Array.from(a.filter((_, i) => keep[i]));
    const k = pick(tr.k);
    const K = pick(tr.K);
    const T = pick(tr.tau);
    const th = thinner(k.length);
    const box = h("section", { class: "card conv-pair" }, h("h2", null, t("run.convergence", { method: methodTitle(f.method) })));
    main.append(box);
    charts.push(
      new Chart(box, { label: t("convergence.kChart", { method: methodTitle(f.method) }), xLabel: t("axis.sample"), yLabel: t("axis.K"), height: 180, series: [{ label: t("series.K") }], source: () => [th(k), th(K)] }),
      new Chart(box, { label: t("convergence.tauChart", { method: methodTitle(f.method) }), xLabel: t("axis.sample"), yLabel: t("axis.tau"), height: 180, series: [{ label: t("series.tau"), color: "#CC79A7" }], source: () => [th(k), th(T)] }),
    );
  }
}

/** Keep every n-th point so that at most MAX_POINTS are drawn. */
function thinner(length) {
  const step = Math.max(1, Math.ceil(length / MAX_POINTS));
  return (a) => (step === 1 ? a : Float64Array.from({ length: Math.ceil(a.length / step) }, (_, i) => a[i * step]));
}

function resultsSection(figures) {
  const sec = h("section", { class: "card", "aria-labelledby": "run-results" }, h("h2", { id: "run-results" }, t("run.results")));
  if (figures.length === 0) {
    sec.append(h("p", { class: "muted" }, t("run.noResults")));
    return sec;
  }
  const spread = (s) => (s && s.max !== s.min ? `${fmtFigure(s.mean)} / ${fmtFigure(s.max)} / ${fmtFigure(s.min)}` : "–");
  const rows = figures.map((f) =>
    h(
      "tr",
      { "data-method": f.method, class: f.valid && !f.trusted ? "not-trusted" : null, "data-trusted": String(f.trusted) },
      h("th", { scope: "row" }, methodTitle(f.method)),
      h("td", { class: "num", "data-field": "K" }, f.valid ? fmtFigure(f.final.K) : "–", f.valid ? lastSampleGain(f.final) : null),
      h("td", { class: "num", "data-field": "tau" }, f.valid ? fmtFigure(f.final.tau) : "–"),
      h("td", { class: "num", "data-field": "theta" }, f.valid ? fmtFigure(f.final.theta) : "–"),
      h("td", { class: "num", "data-field": "Kstats" }, spread(f.K)),
      h("td", { class: "num", "data-field": "taustats" }, spread(f.tau)),
      h("td", { class: "num", "data-field": "conv" }, f.converges ? t("run.convergedAt", { K: f.convergedAt.K ?? t("run.never"), tau: f.convergedAt.tau ?? t("run.never") }) : "–"),
      h("td", null, reasonCell(f)),
    ),
  );
  sec.append(
    h(
      "div",
      { class: "table-wrap", tabindex: "0", role: "region", "aria-label": t("run.resultsTable") },
      h(
        "table",
        null,
        h("caption", { class: "visually-hidden" }, t("run.resultsCaption")),
        h(
          "thead",
          null,
          h(
            "tr",
            null,
            h("th", { scope: "col" }, t("table.method")),
            h("th", { scope: "col", class: "num" }, t("table.K")),
            h("th", { scope: "col", class: "num" }, t("table.tau")),
            h("th", { scope: "col", class: "num" }, t("table.theta")),
            h("th", { scope: "col", class: "num" }, t("run.Kstats")),
            h("th", { scope: "col", class: "num" }, t("run.tauStats")),
            h("th", { scope: "col", class: "num" }, t("run.convergeColumn")),
            h("th", { scope: "col" }, t("run.notes")),
          ),
        ),
        h("tbody", null, rows),
      ),
    ),
  );
  return sec;
}
