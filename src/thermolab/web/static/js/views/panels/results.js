// @ts-check
// What a panel says about its run: the status line, the operating point and
// the table of the current estimates of each of its methods.

import { h, serverText, setText, tParts } from "../../dom.js";
import { fmt } from "../../model.js";
import { methodName, methodTitle, panelOfRun, runStatusText } from "../../runspec.js";
import { DEFAULT_LANGUAGE, formatDecimal, language, t } from "../../i18n.js";
import { OFFSET_LABELS } from "./definitions.js";

/**
 * How a run handled the operating point (RunOut.operatingPoint), in words,
 * or "" when the run says nothing. The server explains its choice in English
 * (`reason`, until its messages are translated): that sentence is shown to
 * English readers; the others read the mode in their language ("inicial"),
 * which the hint under the panel's select explains.
 */
export function operatingPointHow(op) {
  if (!op || typeof op !== "object") return "";
  if (op.used === null || op.used === undefined) return "";
  if (op.reason && language() === DEFAULT_LANGUAGE) return String(op.reason);
  const label = OFFSET_LABELS[op.used];
  return label ? t(label) : typeof op.used === "number" ? formatDecimal(op.used) : String(op.used);
}

/** The panel's sentence on the operating point ("" when the run says nothing). */
export function operatingPointText(op) {
  const how = operatingPointHow(op);
  return how ? t("panel.operatingPointUsed", { how }) : "";
}

/** What an estimate's status cell says: final or live, and why there is no model. */
export function estimateStatus(est) {
  if (!est) return t("estimate.waiting");
  const when = est.final ? t("estimate.final") : t("estimate.live");
  if (est.valid) return when;
  return tParts("estimate.withReason", { when, reason: est.reason ? serverText(est.reason) : t("estimate.noModel") });
}

/** The status line of the panel running `run`: its progress. */
export function runningText(run, k) {
  const n = run.nSamples;
  const key = n ? (run.signal ? "panel.runningOfAutomatic" : "panel.runningOf") : run.signal ? "panel.runningAutomatic" : "panel.running";
  return t(key, { run: run.id, sample: k, samples: n });
}

/**
 * The status line of a panel whose run ended, or that has had none (DOM
 * children: the server's end reason is its own sentence, see serverText).
 * @returns {Array<Node | string>}
 */
export function idleParts(run, panelId) {
  if (run && panelOfRun(run) === panelId) {
    return run.endReason
      ? tParts("panel.endedWhy", { run: run.id, status: runStatusText(run.status), reason: serverText(run.endReason) })
      : [t("panel.ended", { run: run.id, status: runStatusText(run.status) })];
  }
  return [t("panel.noRun")];
}

/** The status line of a panel while another panel's run is going. */
export function otherRunText(runPanel, number) {
  return t("panel.otherRun", { method: methodTitle(runPanel), panel: number ?? "?" });
}

/**
 * Fill a panel's results with the estimates of `run` (null: the panel's methods, empty).
 * @param {{def: any, results: HTMLElement, operatingPoint: HTMLElement}} view
 * @param {any} run
 */
export function renderResults(view, run) {
  setText(view.operatingPoint, operatingPointText(run?.operatingPoint));
  view.operatingPoint.hidden = !view.operatingPoint.textContent;
  const asked = new Set(run ? run.methods.map(methodName) : []);
  const shown = view.def.methods.filter((m) => !(view.def.optional ?? []).includes(m) || asked.has(m));
  const rows = shown.map((m) => {
    const est = run?.estimates?.get(m) ?? null;
    return h(
      "tr",
      { "data-method": m },
      h("th", { scope: "row" }, methodTitle(m)),
      h("td", { "data-field": "K" }, est ? fmt(est.K) : "–"),
      h("td", { "data-field": "tau" }, est ? fmt(est.tau) : "–"),
      h("td", { "data-field": "k" }, est && Number.isFinite(est.k) ? String(est.k) : "–"),
      h("td", { "data-field": "status" }, estimateStatus(est)),
    );
  });
  const col = (text) => h("th", { scope: "col" }, text);
  view.results.replaceChildren(
    h(
      "div",
      { class: "table-wrap", tabindex: "0", role: "region", "aria-label": t("panel.estimatesRegion", { title: view.def.title }) },
      h(
        "table",
        { class: "estimates" },
        h("caption", { class: "visually-hidden" }, t("panel.estimatesCaption", { title: view.def.title })),
        h("thead", null, h("tr", null, col(t("table.method")), col(t("table.K")), col(t("table.tau")), col(t("table.atSample")), col(t("table.status")))),
        h("tbody", null, rows),
      ),
    ),
  );
}
