// One run: what was asked, its charts (output with the model, input, and the
// convergence of the recursive methods), every method's results, the CSV.

import { api } from "../api.js";
import { Chart } from "../charts.js";
import { h, setText, when } from "../dom.js";
import { fmt, predict, predictionBase } from "../model.js";
import { readResult } from "../results.js";
import { inputText, methodTitle, readRun } from "../runspec.js";

/** At most this many points per chart: longer runs are drawn decimated. */
const MAX_POINTS = 4000;

/**
 * A run's figures per method: the stored results once the run has ended,
 * else the latest estimates of the running run.
 * @param {any} exported  GET /api/runs/{run}/export.json
 */
export function runFigures(exported) {
  const run = readRun(exported.run);
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
  ctx.setTitle(`Run ${id}`);
  const status = h("p", { class: "muted", role: "status" }, "Loading…");
  main.append(h("p", { class: "crumbs" }, h("a", { href: "#/runs" }, "My runs"), ` › run ${id}`), h("h1", null, `Run ${id}`), status);
  const abort = new AbortController();
  const charts = [];
  (async () => {
    let exported;
    try {
      exported = await api.exportRun(id, { signal: abort.signal });
    } catch (err) {
      if (err.name !== "AbortError") setText(status, `Could not load run ${id}: ${err.message}`);
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
  add("Rig", run.rig ?? "–");
  if (run.user) add("Student", run.user);
  add("Status", run.status + (run.endReason ? ` (${run.endReason})` : ""));
  add("Started", when(run.startedAt));
  add("Ended", when(run.endedAt));
  add("Sample time", `${run.dt} s`);
  add("Samples", `${run.samples}${run.nSamples ? ` of ${run.nSamples}` : ""}`);
  add("Input", inputText(run));
  add("Methods", run.methods.map(methodTitle).join(", "));
  const settings = Object.entries(run.settings ?? {}).filter(([, v]) => v !== null && typeof v !== "object");
  if (settings.length) add("Settings", settings.map(([k, v]) => `${k} = ${v}`).join(", "));
  const w0 = run.settings?.w0;
  if (Array.isArray(w0)) add("Initial parameters W0", `[${w0.map((v) => fmt(v)).join(", ")}]`);
  if (run.operatingPoint?.used !== null && run.operatingPoint?.used !== undefined) {
    facts.append(h("dt", null, "Operating point"), h("dd", { "data-testid": "operating-point" }, run.operatingPoint.reason ?? String(run.operatingPoint.used)));
  }
  main.append(
    h(
      "section",
      { class: "card" },
      h("h2", null, "The run"),
      facts,
      h(
        "div",
        { class: "buttons" },
        h("a", { class: "button primary", href: api.csvUrl(run.id), download: `run-${run.id}.csv`, "data-testid": "csv-link" }, "Download the samples (CSV)"),
        h("a", { class: "button", href: api.exportUrl(run.id), download: `run-${run.id}.json` }, "Everything (JSON)"),
      ),
    ),
  );
  main.append(resultsSection(figures));

  const samples = exported.samples ?? {};
  const t = Float64Array.from(samples.t ?? []);
  const u = Float64Array.from(samples.u ?? []);
  const y = Float64Array.from(samples.y ?? []);
  const chartBox = h("section", { class: "card", "aria-labelledby": "run-charts" }, h("h2", { id: "run-charts" }, "Charts"));
  const modelPick = h("select", { id: "run-model" });
  const withModel = figures.filter((f) => f.valid && f.final.K !== null && f.final.tau > 0);
  modelPick.append(h("option", { value: "" }, "none"), ...withModel.map((f, i) => h("option", { value: String(i) }, methodTitle(f.method))));
  const lsm = withModel.findIndex((f) => f.method === "lsm");
  if (withModel.length) modelPick.value = String(lsm >= 0 ? lsm : 0);
  chartBox.append(h("div", { class: "field inline" }, h("label", { for: "run-model" }, "Model drawn over the output"), modelPick));
  main.append(chartBox);
  const yhat = new Float64Array(y.length).fill(Number.NaN);
  const computeModel = () => {
    const f = modelPick.value === "" ? null : withModel[Number(modelPick.value)];
    if (!f || y.length === 0) yhat.fill(Number.NaN);
    else {
      const base = predictionBase(run.operatingPoint?.used, f.final.W, y[0]);
      predict(u, base, { K: f.final.K, tau: f.final.tau }, run.dt, yhat, y[0] - base);
    }
  };
  computeModel();
  const thin = thinner(t.length);
  const out = new Chart(chartBox, {
    label: `Output and model of run ${run.id}`,
    xLabel: "t (s)",
    yLabel: "y (V)",
    series: [{ label: "output y" }, { label: "model", dash: [6, 4], color: "#D55E00", width: 2, auto: false }],
    source: () => [thin(t), thin(y), thin(yhat)],
  });
  const inp = new Chart(chartBox, {
    label: `Input of run ${run.id}`,
    xLabel: "t (s)",
    yLabel: "u (V)",
    height: 160,
    series: [{ label: "input u", color: "#009E73" }],
    source: () => [thin(t), thin(u)],
  });
  charts.push(out, inp);
  modelPick.addEventListener("change", () => {
    computeModel();
    out.invalidate();
  });

  for (const f of figures) {
    if (!f.trajectory) continue;
    // Only estimates with a first-order meaning are drawn (uPlot has no NaN gaps).
    const keep = f.trajectory.k.map((_, i) => Number.isFinite(f.trajectory.K[i]) && Number.isFinite(f.trajectory.tau[i]));
    const pick = (a) => Float64Array.from(a.filter((_, i) => keep[i]));
    const k = pick(f.trajectory.k);
    const K = pick(f.trajectory.K);
    const T = pick(f.trajectory.tau);
    const th = thinner(k.length);
    const box = h("section", { class: "card conv-pair" }, h("h2", null, `Convergence: ${methodTitle(f.method)}`));
    main.append(box);
    charts.push(
      new Chart(box, { label: `Ks against sample, ${methodTitle(f.method)}`, xLabel: "sample k", yLabel: "Ks", height: 180, series: [{ label: "Ks(k)" }], source: () => [th(k), th(K)] }),
      new Chart(box, { label: `Ts against sample, ${methodTitle(f.method)}`, xLabel: "sample k", yLabel: "Ts (s)", height: 180, series: [{ label: "Ts(k)", color: "#CC79A7" }], source: () => [th(k), th(T)] }),
    );
  }
}

/** Keep every n-th point so that at most MAX_POINTS are drawn. */
function thinner(length) {
  const step = Math.max(1, Math.ceil(length / MAX_POINTS));
  return (a) => (step === 1 ? a : Float64Array.from({ length: Math.ceil(a.length / step) }, (_, i) => a[i * step]));
}

function resultsSection(figures) {
  const sec = h("section", { class: "card", "aria-labelledby": "run-results" }, h("h2", { id: "run-results" }, "Results"));
  if (figures.length === 0) {
    sec.append(h("p", { class: "muted" }, "No results stored for this run."));
    return sec;
  }
  const spread = (s) => (s && s.max !== s.min ? `${fmt(s.mean)} / ${fmt(s.max)} / ${fmt(s.min)}` : "–");
  const rows = figures.map((f) =>
    h(
      "tr",
      { "data-method": f.method },
      h("th", { scope: "row" }, methodTitle(f.method)),
      h("td", { class: "num", "data-field": "K" }, f.valid ? fmt(f.final.K) : "–"),
      h("td", { class: "num", "data-field": "tau" }, f.valid ? fmt(f.final.tau) : "–"),
      h("td", { class: "num", "data-field": "Kstats" }, spread(f.K)),
      h("td", { class: "num", "data-field": "taustats" }, spread(f.tau)),
      h("td", { class: "num", "data-field": "conv" }, f.converges ? `${f.convergedAt.K ?? "never"} / ${f.convergedAt.tau ?? "never"}` : "–"),
      h("td", null, [f.valid ? "" : (f.reason ?? "no first-order model"), ...f.warnings].filter(Boolean).join("; ") || "–"),
    ),
  );
  sec.append(
    h(
      "div",
      { class: "table-wrap", tabindex: "0", role: "region", "aria-label": "Results table" },
      h(
        "table",
        null,
        h("caption", { class: "visually-hidden" }, "Each method's model; statistics over the last 2000 samples"),
        h(
          "thead",
          null,
          h(
            "tr",
            null,
            h("th", { scope: "col" }, "Method"),
            h("th", { scope: "col", class: "num" }, "Ks"),
            h("th", { scope: "col", class: "num" }, "Ts (s)"),
            h("th", { scope: "col", class: "num" }, "Ks mean / max / min"),
            h("th", { scope: "col", class: "num" }, "Ts mean / max / min"),
            h("th", { scope: "col", class: "num" }, "Samples to converge Ks / Ts"),
            h("th", { scope: "col" }, "Notes"),
          ),
        ),
        h("tbody", null, rows),
      ),
    ),
  );
  return sec;
}
