// My runs: the list, with a choice of runs to compare against the reference model.

import { api } from "../api.js";
import { h, setText, when } from "../dom.js";
import { inputText, methodName, methodTitle, panelOfRun, readRun } from "../runspec.js";

/**
 * A table of runs; with `selectable`, each row has a checkbox named "run".
 * @param {any[]} runs
 * @param {{showUser?: boolean, selectable?: boolean}} [opts]
 */
export function runsTable(runs, opts = {}) {
  const list = runs.map(readRun).filter(Boolean);
  if (list.length === 0) return h("p", { class: "muted" }, "No runs yet.");
  const head = [
    opts.selectable ? h("th", { scope: "col" }, h("span", { class: "visually-hidden" }, "Compare")) : null,
    h("th", { scope: "col" }, "Run"),
    opts.showUser ? h("th", { scope: "col" }, "Student") : null,
    h("th", { scope: "col" }, "Rig"),
    h("th", { scope: "col" }, "Started"),
    h("th", { scope: "col" }, "Methods"),
    h("th", { scope: "col" }, "Input"),
    h("th", { scope: "col", class: "num" }, "Samples"),
    h("th", { scope: "col" }, "Status"),
  ];
  const rows = list.map((run) => {
    const label = `Run ${run.id}`;
    return h(
      "tr",
      { "data-run": run.id },
      opts.selectable
        ? h("td", null, h("input", { type: "checkbox", name: "run", value: run.id, id: `pick-${run.id}`, "aria-label": `Compare ${label}` }))
        : null,
      h("td", null, h("a", { href: `#/runs/${encodeURIComponent(run.id)}` }, label)),
      opts.showUser ? h("td", null, run.user ?? "–") : null,
      h("td", null, run.rig ?? "–"),
      h("td", null, when(run.startedAt)),
      h("td", null, run.methods.map((m) => methodTitle(methodName(m))).join(", ") || methodTitle(panelOfRun(run))),
      h("td", null, inputText(run)),
      h("td", { class: "num" }, String(run.samples)),
      h("td", null, run.status + (run.endReason ? ` (${run.endReason})` : "")),
    );
  });
  return h("table", { class: "runs" }, h("caption", { class: "visually-hidden" }, "Runs"), h("thead", null, h("tr", null, head)), h("tbody", null, rows));
}

/**
 * Runs with a checkbox each and a button to compare the chosen ones.
 * @param {any[]} runs  RunOut list
 * @param {{navigate: (path: string) => void}} ctx
 * @param {{showUser?: boolean, label?: string}} [opts]
 */
export function runsPicker(runs, ctx, opts = {}) {
  const box = h("div", { class: "table-wrap", tabindex: "0", role: "region", "aria-label": opts.label ?? "Runs" }, runsTable(runs, { ...opts, selectable: true }));
  const error = h("p", { class: "error", role: "alert" });
  const compare = h("button", { type: "submit", class: "primary", hidden: runs.length === 0 }, "Compare the chosen runs");
  const form = h("form", { novalidate: true }, box, error, h("div", { class: "buttons" }, compare));
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    const ids = [...form.querySelectorAll('input[name="run"]:checked')].map((c) => c.value);
    if (ids.length === 0) {
      setText(error, "Choose at least one run to compare.");
      form.querySelector('input[name="run"]')?.focus();
      return;
    }
    ctx.navigate(`/runs/compare?ids=${ids.map(encodeURIComponent).join(",")}`);
  });
  return form;
}

export function mount(main, _params, ctx) {
  const status = h("p", { class: "muted", role: "status" }, "Loading…");
  const host = h("div");
  main.append(
    h("h1", null, "My runs"),
    h("p", { class: "lede" }, "Every run you made, newest first. Open one for its charts, results and CSV, or tick several and compare them with the reference model, as in the paper's Tables I and II."),
    status,
    host,
  );
  const abort = new AbortController();
  (async () => {
    try {
      // Only the user's own runs (a teacher would otherwise be sent everyone's).
      const data = await api.runs(`?user=${encodeURIComponent(ctx.user?.username ?? "")}`, { signal: abort.signal });
      host.replaceChildren(runsPicker(Array.isArray(data) ? data : [], ctx, { label: "Your runs" }));
      setText(status, "");
    } catch (err) {
      if (err.name !== "AbortError") setText(status, `Could not load your runs: ${err.message}`);
    }
  })();
  return () => abort.abort();
}
