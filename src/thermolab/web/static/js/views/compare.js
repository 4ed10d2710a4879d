// Chosen runs against a reference model, in the form of the paper's Tables I
// and II: Ks and Ts (mean / max / min for the methods that give many
// estimates), their deviation from the reference, samples to converge.

import { api } from "../api.js";
import { h, setText } from "../dom.js";
import { deviation, fmt, REFERENCE_MODEL } from "../model.js";
import { inputText, methodTitle } from "../runspec.js";
import { runFigures } from "./run.js";
import { checkNumber, rangeText } from "../validate.js";

const KREF = { label: "Reference Ks", min: -1e6, max: 1e6 };
const TREF = { label: "Reference Ts", min: 0, max: 1e9, exclusiveMin: true, unit: "s" };

export function mount(main, { query }, ctx) {
  const ids = (query.get("ids") ?? "").split(",").map((s) => s.trim()).filter(Boolean);
  const kIn = h("input", { id: "ref-k", value: String(REFERENCE_MODEL.K), autocomplete: "off", "aria-describedby": "ref-k-hint ref-error" });
  const tIn = h("input", { id: "ref-tau", value: String(REFERENCE_MODEL.tau), autocomplete: "off", "aria-describedby": "ref-tau-hint ref-error" });
  const refError = h("p", { class: "error", id: "ref-error", role: "alert" });
  const refForm = h(
    "form",
    { novalidate: true, class: "card" },
    h(
      "fieldset",
      null,
      h("legend", null, "Reference model"),
      h("p", { class: "hint" }, "Default: the paper's eq. 16 (Ks = 0.140090, Ts = 250.126233 s), the model the step method found on the real rig."),
      h("div", { class: "field" }, h("label", { for: "ref-k" }, "Ks"), kIn, h("span", { class: "hint", id: "ref-k-hint" }, `Allowed: ${rangeText(KREF)}`)),
      h("div", { class: "field" }, h("label", { for: "ref-tau" }, "Ts (s)"), tIn, h("span", { class: "hint", id: "ref-tau-hint" }, `Allowed: ${rangeText(TREF)}`)),
      h("div", { class: "buttons" }, h("button", { type: "submit" }, "Compare with this reference")),
    ),
    refError,
  );
  const status = h("p", { class: "muted", role: "status" }, "Loading…");
  const tableBox = h("div", { class: "table-wrap", tabindex: "0", role: "region", "aria-label": "Comparison table" });
  main.append(
    h("p", { class: "crumbs" }, h("a", { href: "#/runs" }, "My runs"), " › compare"),
    h("h1", null, "Compare runs with the reference model"),
    refForm,
    status,
    tableBox,
  );
  let ref = { ...REFERENCE_MODEL };
  let runs = [];
  refForm.addEventListener("submit", (ev) => {
    ev.preventDefault();
    const k = checkNumber(kIn.value, KREF);
    const t = checkNumber(tIn.value, TREF);
    kIn.toggleAttribute("aria-invalid", !k.ok);
    tIn.toggleAttribute("aria-invalid", !t.ok);
    if (!k.ok || !t.ok) {
      setText(refError, [k.ok ? "" : k.error, t.ok ? "" : t.error].filter(Boolean).join(" "));
      (k.ok ? tIn : kIn).focus();
      return;
    }
    setText(refError, "");
    ref = { K: k.value, tau: t.value };
    tableBox.replaceChildren(comparisonTable(runs, ref));
  });
  if (ids.length === 0) {
    setText(status, "No runs chosen: tick some in My runs.");
    return null;
  }
  const abort = new AbortController();
  (async () => {
    const answers = await Promise.allSettled(ids.map((id) => api.exportRun(id, { signal: abort.signal })));
    if (abort.signal.aborted) return;
    const failed = [];
    runs = [];
    answers.forEach((a, i) => (a.status === "fulfilled" ? runs.push(runFigures(a.value)) : failed.push(`run ${ids[i]}: ${a.reason.message}`)));
    setText(status, failed.length ? `Not shown: ${failed.join("; ")}` : "");
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
  if (rows.length === 0) return h("p", { class: "muted" }, "The chosen runs have no results yet.");
  const mmm = (s) => (s ? (s.max === s.min ? fmt(s.mean) : `${fmt(s.mean)} / ${fmt(s.max)} / ${fmt(s.min)}`) : "–");
  const dev = (s, refValue) => {
    const d = s ? deviation(s.mean, refValue) : null;
    if (!d) return "–";
    return `${fmt(d.abs, 4)} (${fmt(100 * d.rel, 3)} %)`;
  };
  const body = rows.map(({ run, label, f }) =>
    h(
      "tr",
      { "data-run": run.id, "data-method": f.method },
      h("th", { scope: "row" }, h("a", { href: `#/runs/${encodeURIComponent(run.id)}` }, `Run ${run.id}`), ` · ${methodTitle(label)}`),
      h("td", null, inputText(run)),
      h("td", { class: "num", "data-field": "K" }, mmm(f.K)),
      h("td", { class: "num", "data-field": "dK" }, dev(f.K, ref.K)),
      h("td", { class: "num", "data-field": "tau" }, mmm(f.tau)),
      h("td", { class: "num", "data-field": "dtau" }, dev(f.tau, ref.tau)),
      h("td", { class: "num", "data-field": "conv" }, f.converges ? `${f.convergedAt.K ?? "never"} / ${f.convergedAt.tau ?? "never"}` : "–"),
    ),
  );
  return h(
    "table",
    { class: "compare" },
    h("caption", null, `Against the reference Ks = ${fmt(ref.K)}, Ts = ${fmt(ref.tau)} s (deviation: mean − reference)`),
    h(
      "thead",
      null,
      h(
        "tr",
        null,
        h("th", { scope: "col" }, "Run · method"),
        h("th", { scope: "col" }, "Input"),
        h("th", { scope: "col", class: "num" }, "Ks mean / max / min"),
        h("th", { scope: "col", class: "num" }, "Ks deviation"),
        h("th", { scope: "col", class: "num" }, "Ts (s) mean / max / min"),
        h("th", { scope: "col", class: "num" }, "Ts deviation"),
        h("th", { scope: "col", class: "num" }, "Samples to converge Ks / Ts"),
      ),
    ),
    h("tbody", null, body),
  );
}
