// @ts-check
// Chosen runs against a reference model, in the form of the paper's Tables I
// and II: Ks and Ts (mean / max / min for the methods that give many
// estimates), their deviation from the reference, samples to converge.

import { api } from "../api.js";
import { h, setText } from "../dom.js";
import { deviation, fmtDeviation, fmtFigure, fmtPercentDeviation, REFERENCE_MODEL } from "../model.js";
import { inputText, methodTitle } from "../runspec.js";
import { runFigures } from "./run.js";
import { lastSampleGain } from "./panels/results.js";
import { checkNumber, rangeText } from "../validate.js";
import { formatDecimal, t } from "../i18n.js";

const KREF = { label: "compare.refK", min: -1e6, max: 1e6 };
const TREF = { label: "compare.refTau", min: 0, max: 1e9, exclusiveMin: true, unit: "s" };

export function mount(main, { query }, _ctx) {
  const ids = (query.get("ids") ?? "").split(",").map((s) => s.trim()).filter(Boolean);
  const kRef = { ...KREF, label: t(KREF.label) };
  const tauRef = { ...TREF, label: t(TREF.label) };
  const kIn = h("input", { id: "ref-k", value: formatDecimal(REFERENCE_MODEL.K), autocomplete: "off", "aria-describedby": "ref-k-hint ref-error" });
  const tIn = h("input", { id: "ref-tau", value: formatDecimal(REFERENCE_MODEL.tau), autocomplete: "off", "aria-describedby": "ref-tau-hint ref-error" });
  const refError = h("p", { class: "error", id: "ref-error", role: "alert" });
  const refForm = h(
    "form",
    { novalidate: true, class: "card" },
    h(
      "fieldset",
      null,
      h("legend", null, t("compare.reference")),
      h("p", { class: "hint" }, t("compare.referenceHint")),
      h("div", { class: "field" }, h("label", { for: "ref-k" }, t("table.K")), kIn, h("span", { class: "hint", id: "ref-k-hint" }, t("field.allowed", { range: rangeText(kRef) }))),
      h("div", { class: "field" }, h("label", { for: "ref-tau" }, t("table.tau")), tIn, h("span", { class: "hint", id: "ref-tau-hint" }, t("field.allowed", { range: rangeText(tauRef) }))),
      h("div", { class: "buttons" }, h("button", { type: "submit" }, t("compare.submit"))),
    ),
    refError,
  );
  const status = h("p", { class: "muted", role: "status" }, t("app.loading"));
  const tableBox = h("div", { class: "table-wrap", tabindex: "0", role: "region", "aria-label": t("compare.table") });
  main.append(
    h("p", { class: "crumbs" }, h("a", { href: "#/runs" }, t("nav.runs")), t("compare.crumb")),
    h("h1", null, t("compare.heading")),
    refForm,
    status,
    tableBox,
  );
  /** @type {{K: number, tau: number}} */
  let ref = { ...REFERENCE_MODEL };
  let runs = [];
  refForm.addEventListener("submit", (ev) => {
    ev.preventDefault();
    const k = checkNumber(kIn.value, kRef);
    const tau = checkNumber(tIn.value, tauRef);
    kIn.toggleAttribute("aria-invalid", !k.ok);
    tIn.toggleAttribute("aria-invalid", !tau.ok);
    if (!k.ok || !tau.ok) {
      setText(refError, [k.ok ? "" : k.error, tau.ok ? "" : tau.error].filter(Boolean).join(" "));
      (k.ok ? tIn : kIn).focus();
      return;
    }
    setText(refError, "");
    ref = { K: k.value, tau: tau.value };
    tableBox.replaceChildren(comparisonTable(runs, ref));
  });
  if (ids.length === 0) {
    setText(status, t("compare.noneChosen"));
    return null;
  }
  const abort = new AbortController();
  (async () => {
    const answers = await Promise.allSettled(ids.map((id) => api.exportRun(id, { signal: abort.signal })));
    if (abort.signal.aborted) return;
    const failed = [];
    runs = [];
    answers.forEach((a, i) => (a.status === "fulfilled" ? runs.push(runFigures(a.value)) : failed.push(t("compare.failedRun", { run: ids[i], error: a.reason.message }))));
    setText(status, failed.length ? t("compare.notShown", { runs: failed.join("; ") }) : "");
    tableBox.replaceChildren(comparisonTable(runs, ref));
  })();
  return () => abort.abort();
}

/**
 * The comparison table.
 * @param {{run: object, figures: import("../results.js").MethodFigures[]}[]} runs
 * @param {{K: number, tau: number}} ref
 */
export function comparisonTable(runs, ref) {
  const rows = [];
  for (const { run, figures } of runs) {
    for (const f of figures) rows.push({ run, label: f.method, f });
  }
  if (rows.length === 0) return h("p", { class: "muted" }, t("compare.noResults"));
  const mmm = (s) => (s ? (s.max === s.min ? fmtFigure(s.mean) : `${fmtFigure(s.mean)} / ${fmtFigure(s.max)} / ${fmtFigure(s.min)}`) : "–");
  const dev = (s, refValue) => {
    const d = s ? deviation(s.mean, refValue) : null;
    if (!d) return "–";
    return `${fmtDeviation(d.abs)} (${fmtPercentDeviation(d.rel)})`;
  };
  const body = rows.map(({ run, label, f }) =>
    h(
      "tr",
      { "data-run": run.id, "data-method": f.method },
      h("th", { scope: "row" }, h("a", { href: `#/runs/${encodeURIComponent(run.id)}` }, t("runs.label", { run: run.id })), t("compare.method", { method: methodTitle(label) })),
      h("td", null, inputText(run)),
      h("td", { class: "num", "data-field": "K" }, mmm(f.K), lastSampleGain(f.final)),
      h("td", { class: "num", "data-field": "dK" }, dev(f.K, ref.K)),
      h("td", { class: "num", "data-field": "tau" }, mmm(f.tau)),
      h("td", { class: "num", "data-field": "dtau" }, dev(f.tau, ref.tau)),
      h("td", { class: "num", "data-field": "theta" }, f.valid ? fmtFigure(f.final.theta) : "–"),
      h("td", { class: "num", "data-field": "conv" }, f.converges ? t("run.convergedAt", { K: f.convergedAt.K ?? t("run.never"), tau: f.convergedAt.tau ?? t("run.never") }) : "–"),
    ),
  );
  return h(
    "table",
    { class: "compare" },
    h("caption", null, t("compare.caption", { K: fmtFigure(ref.K), tau: fmtFigure(ref.tau) })),
    h(
      "thead",
      null,
      h(
        "tr",
        null,
        h("th", { scope: "col" }, t("compare.runMethod")),
        h("th", { scope: "col" }, t("runs.input")),
        h("th", { scope: "col", class: "num" }, t("run.Kstats")),
        h("th", { scope: "col", class: "num" }, t("compare.Kdeviation")),
        h("th", { scope: "col", class: "num" }, t("compare.tauStats")),
        h("th", { scope: "col", class: "num" }, t("compare.tauDeviation")),
        h("th", { scope: "col", class: "num" }, t("table.theta")),
        h("th", { scope: "col", class: "num" }, t("run.convergeColumn")),
      ),
    ),
    h("tbody", null, body),
  );
}
