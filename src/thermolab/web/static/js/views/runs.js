// @ts-check
// My runs: the list, with a choice of runs to compare against the reference model.

import { api } from "../api.js";
import { h, setText, when } from "../dom.js";
import { inputText, methodName, methodTitle, panelOfRun, readRun, runStatusText } from "../runspec.js";
import { statusParts } from "../runwords.js";
import { t } from "../i18n.js";
import { personName } from "../shapes.js";

/**
 * A table of runs; with `selectable`, each row has a checkbox named "run".
 * @param {any[]} runs
 * @param {{showUser?: boolean, selectable?: boolean}} [opts]
 */
export function runsTable(runs, opts = {}) {
  const list = runs.map(readRun).filter((r) => r !== null);
  if (list.length === 0) return h("p", { class: "muted" }, t("runs.none"));
  const head = [
    opts.selectable ? h("th", { scope: "col" }, h("span", { class: "visually-hidden" }, t("runs.compareColumn"))) : null,
    h("th", { scope: "col" }, t("runs.run")),
    opts.showUser ? h("th", { scope: "col" }, t("runs.student")) : null,
    h("th", { scope: "col" }, t("runs.rig")),
    h("th", { scope: "col" }, t("runs.started")),
    h("th", { scope: "col" }, t("runs.methods")),
    h("th", { scope: "col" }, t("runs.input")),
    h("th", { scope: "col", class: "num" }, t("runs.samples")),
    h("th", { scope: "col" }, t("runs.status")),
  ];
  const rows = list.map((run) => {
    const label = t("runs.label", { run: run.id });
    return h(
      "tr",
      { "data-run": run.id },
      opts.selectable
        ? h("td", null, h("input", { type: "checkbox", name: "run", value: run.id, id: `pick-${run.id}`, "aria-label": t("runs.compareOne", { run: label }) }))
        : null,
      h("td", null, h("a", { href: `#/runs/${encodeURIComponent(run.id)}` }, label)),
      opts.showUser ? h("td", null, run.user ? personName(run.user, run.userName, true) : "–") : null,
      h("td", null, run.rig ?? "–"),
      h("td", null, when(run.startedAt)),
      h("td", null, run.methods.map((m) => methodTitle(methodName(m))).join(", ") || methodTitle(panelOfRun(run))),
      h("td", null, inputText(run)),
      h("td", { class: "num" }, String(run.samples)),
      h("td", null, statusParts(run, runStatusText)),
    );
  });
  return h("table", { class: "runs" }, h("caption", { class: "visually-hidden" }, t("runs.caption")), h("thead", null, h("tr", null, head)), h("tbody", null, rows));
}

/**
 * Runs with a checkbox each and a button to compare the chosen ones.
 * @param {any[]} runs  RunOut list
 * @param {{navigate: (path: string) => void}} ctx
 * @param {{showUser?: boolean, label?: string}} [opts]
 */
export function runsPicker(runs, ctx, opts = {}) {
  const box = h("div", { class: "table-wrap", tabindex: "0", role: "region", "aria-label": opts.label ?? t("runs.caption") }, runsTable(runs, { ...opts, selectable: true }));
  const error = h("p", { class: "error", role: "alert" });
  const compare = h("button", { type: "submit", class: "primary", hidden: runs.length === 0 }, t("runs.compare"));
  const form = h("form", { novalidate: true }, box, error, h("div", { class: "buttons" }, compare));
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    const ids = [...form.querySelectorAll('input[name="run"]:checked')].map((c) => /** @type {HTMLInputElement} */ (c).value);
    if (ids.length === 0) {
      setText(error, t("runs.chooseOne"));
      form.querySelector("input")?.focus();
      return;
    }
    ctx.navigate(`/runs/compare?ids=${ids.map(encodeURIComponent).join(",")}`);
  });
  return form;
}

export function mount(main, _params, ctx) {
  const status = h("p", { class: "muted", role: "status" }, t("app.loading"));
  const host = h("div");
  main.append(
    h("h1", null, t("nav.runs")),
    h("p", { class: "lede" }, t("runs.lede")),
    status,
    host,
  );
  const abort = new AbortController();
  (async () => {
    try {
      // Only the user's own runs (a teacher would otherwise be sent everyone's).
      const data = await api.runs(`?user=${encodeURIComponent(ctx.user?.username ?? "")}`, { signal: abort.signal });
      host.replaceChildren(runsPicker(Array.isArray(data) ? data : [], ctx, { label: t("runs.yours") }));
      setText(status, "");
    } catch (err) {
      if (err.name !== "AbortError") setText(status, t("runs.failed", { error: err.message }));
    }
  })();
  return () => abort.abort();
}
