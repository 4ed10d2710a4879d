// One run: what was asked, its charts (output with the model, input, and the
// convergence of the recursive methods), every method's results, and the CSV.

import { api } from "../api.js";
import { Chart } from "../charts.js";
import { parseCsv } from "../csv.js";
import { h, setText, when } from "../dom.js";
import { fmt, predict } from "../model.js";
import { readResult } from "../results.js";
import { inputText, methodName, methodTitle, readRun } from "../runspec.js";

/** At most this many points per chart: longer runs are drawn decimated. */
const MAX_POINTS = 4000;

export function mount(main, { params }, ctx) {
  const id = params[0];
  ctx.setTitle(`Run ${id}`);
  const status = h("p", { class: "muted", role: "status" }, "Loading…");
  main.append(h("p", { class: "crumbs" }, h("a", { href: "#/runs" }, "My runs"), ` › run ${id}`), h("h1", null, `Run ${id}`), status);
  const abort = new AbortController();
  const charts = [];
  (async () => {
    let run;
    try {
      run = readRun(await api.run(id, { signal: abort.signal }));
    } catch (err) {
      if (err.name !== "AbortError") setText(status, `Could not load run ${id}: ${err.message}`);
      return;
    }
    setText(status, "");
    render(main, run, charts, abort.signal);
  })();
  return () => {
    abort.abort();
    for (const c of charts) c.destroy();
  };
}

function render(main, run, charts, signal) {
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
  add("Methods", run.methods.map((m) => methodTitle(methodName(m))).join(", "));
  const csv = h("a", { class: "button primary", href: api.csvUrl(run.id), download: `run-${run.id}.csv`, "data-testid": "csv-link" }, "Download the samples (CSV)");
  main.append(
    h("section", { class: "card" }, h("h2", null, "The run"), facts, h("div", { class: "buttons" }, csv)),
  );

  const figures = run.results.map((r) => ({ label: r.label ?? r.method, params: r.params ?? {}, ...readResult(r.result ?? r, r.method) }));
  main.append(resultsSection(figures));

  const chartBox = h("section", { class: "card", "aria-labelledby": "run-charts" }, h("h2", { id: "run-charts" }, "Charts"));
  const modelPick = h("select", { id: "run-model" });
  const withModel = figures.filter((f) => f.final.K !== null && f.final.tau > 0);
  modelPick.append(h("option", { value: "" }, "none"), ...withModel.map((f, i) => h("option", { value: String(i) }, methodTitle(f.method))));
  if (withModel.length) modelPick.value = String(withModel.findIndex((f) => f.method === "lsm") >= 0 ? withModel.findIndex((f) => f.method === "lsm") : 0);
  chartBox.append(h("div", { class: "field inline" }, h("label", { for: "run-model" }, "Model drawn over the output"), modelPick));
  main.append(chartBox);

  (async () => {
    let table;
    try {
      const res = await fetch(api.csvUrl(run.id), { credentials: "same-origin", signal });
      if (!res.ok) throw new Error(`${res.status} ${res.statusText}`);
      table = parseCsv(await res.text(), ["t", "u", "y"]);
    } catch (err) {
      if (err.name !== "AbortError") chartBox.append(h("p", { class: "error" }, `Could not load the samples: ${err.message}`));
      return;
    }
    const { t, u, y } = table;
    const yhatFull = new Float64Array(y.length).fill(Number.NaN);
    const computeModel = () => {
      const f = modelPick.value === "" ? null : withModel[Number(modelPick.value)];
      if (!f || y.length === 0) yhatFull.fill(Number.NaN);
      else predict(u, y[0], { K: f.final.K, tau: f.final.tau }, run.dt, yhatFull);
    };
    computeModel();
    const step = Math.max(1, Math.ceil(t.length / MAX_POINTS));
    const thin = (a) => (step === 1 ? a : Float64Array.from({ length: Math.ceil(a.length / step) }, (_, i) => a[i * step]));
    const out = new Chart(chartBox, {
      label: `Output and model of run ${run.id}`,
      xLabel: "t (s)",
      yLabel: "y (V)",
      series: [{ label: "output y" }, { label: "model", dash: [6, 4], color: "#D55E00", width: 2 }],
      source: () => [thin(t), thin(y), thin(yhatFull)],
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
  })();

  for (const f of figures) {
    if (!f.trajectory) continue;
    const k = Float64Array.from(f.trajectory.K, (_, i) => i);
    const K = Float64Array.from(f.trajectory.K, (v) => (v === null ? Number.NaN : v));
    const T = Float64Array.from(f.trajectory.tau, (v) => (v === null ? Number.NaN : v));
    const step = Math.max(1, Math.ceil(k.length / MAX_POINTS));
    const thin = (a) => (step === 1 ? a : Float64Array.from({ length: Math.ceil(a.length / step) }, (_, i) => a[i * step]));
    const box = h("section", { class: "card conv-pair" }, h("h2", null, `Convergence: ${methodTitle(f.method)}`));
    main.append(box);
    charts.push(
      new Chart(box, { label: `Ks against sample, ${methodTitle(f.method)}`, xLabel: "sample k", yLabel: "Ks", height: 180, series: [{ label: "Ks(k)" }], source: () => [thin(k), thin(K)] }),
      new Chart(box, { label: `Ts against sample, ${methodTitle(f.method)}`, xLabel: "sample k", yLabel: "Ts (s)", height: 180, series: [{ label: "Ts(k)", color: "#CC79A7" }], source: () => [thin(k), thin(T)] }),
    );
  }
}

function resultsSection(figures) {
  const sec = h("section", { class: "card", "aria-labelledby": "run-results" }, h("h2", { id: "run-results" }, "Results"));
  if (figures.length === 0) {
    sec.append(h("p", { class: "muted" }, "No results stored for this run."));
    return sec;
  }
  const rows = figures.map((f) =>
    h(
      "tr",
      { "data-method": f.method },
      h("th", { scope: "row" }, methodTitle(f.method)),
      h("td", { class: "num", "data-field": "K" }, fmt(f.final.K)),
      h("td", { class: "num", "data-field": "tau" }, fmt(f.final.tau)),
      h("td", { class: "num" }, f.K && f.K.max !== f.K.min ? `${fmt(f.K.mean)} / ${fmt(f.K.max)} / ${fmt(f.K.min)}` : "–"),
      h("td", { class: "num" }, f.tau && f.tau.max !== f.tau.min ? `${fmt(f.tau.mean)} / ${fmt(f.tau.max)} / ${fmt(f.tau.min)}` : "–"),
      h("td", { class: "num" }, f.convergedAt.K === null && f.convergedAt.tau === null ? "–" : `${f.convergedAt.K ?? "never"} / ${f.convergedAt.tau ?? "never"}`),
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
