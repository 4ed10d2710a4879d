// @ts-check
// What a panel says about its run: the status line, the operating point and
// the table of the current estimates of each of its methods.

import { duration, durationWords, h, setText, tParts } from "../../dom.js";
import { fmtFigure } from "../../model.js";
import { isPlannedStep, methodName, methodTitle, panelOfRun, runPair, runStatusText } from "../../runspec.js";
import { DEFAULT_LANGUAGE, formatDecimal, formatTime, language, t } from "../../i18n.js";
import { OFFSET_LABELS } from "./definitions.js";
import { endReasonNode } from "../../runwords.js";
import { identReason, identWarning } from "../../identwords.js";
import { formatQuantity } from "../../quantities.js";
import { pairLabel } from "../../channelwords.js";

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

/**
 * The operating point each method used and found (the library's decision for
 * offset "auto": handling, how the record starts, the ambient), one line each.
 * @param {string[]} methods
 * @param {Map<string, any>} estimates
 */
export function operatingPointsFound(methods, estimates) {
  const lines = [];
  for (const m of methods) {
    const op = estimates?.get(m)?.operatingPoint;
    if (!op || !op.handling) continue;
    const ambient = formatQuantity(typeof op.ambient === "number" ? op.ambient : null, "volts");
    const label = OFFSET_LABELS[op.handling];
    const handling = label ? t(label) : String(op.handling);
    // The library explains its decision in English: shown to English readers only.
    const reason = op.reason && language() === DEFAULT_LANGUAGE ? ` (${op.reason})` : "";
    lines.push(t("panel.operatingPointFound", { method: methodTitle(m), handling, ambient, reason }));
  }
  return lines;
}

/** What an estimate's status cell says: final or live, not trusted, and why there is no model. */
export function estimateStatus(est) {
  if (!est) return t("estimate.waiting");
  // An estimate the library does not trust never looks final.
  const when = est.trusted === false ? t("estimate.notTrusted") : est.final ? t("estimate.final") : t("estimate.live");
  if (est.valid) return when;
  return tParts("estimate.withReason", { when, reason: est.reason ? identReason(est.reason) : t("estimate.noModel") });
}

/**
 * Every warning of the run's estimates, per method: what it means and what to
 * do is in each line (the library's own words); null when there are none.
 * @param {string[]} methods
 * @param {Map<string, any>} estimates
 * @param {any} [timing]  the run's timing (RunOut.timing): its warning concerns every method
 */
export function warningsList(methods, estimates, timing = null) {
  const items = [];
  for (const w of timing?.warnings ?? []) items.push(h("li", { "data-method": "timing" }, identWarning(w)));
  for (const m of methods) {
    if (estimates?.get(m)?.notConverged) items.push(h("li", { "data-method": m, "data-kind": "not-converged" }, t("panel.notConverged", { method: methodTitle(m) })));
    for (const w of estimates?.get(m)?.warnings ?? []) items.push(h("li", { "data-method": m }, tParts("panel.warning", { method: methodTitle(m), warning: identWarning(w) })));
  }
  if (!items.length) return null;
  return h(
    "div",
    { class: "estimate-warnings", role: "note", "data-testid": "estimate-warnings" },
    h("p", null, t("panel.warningsIntro")),
    h("ul", null, items),
  );
}

/** The status line of the panel running `run`: its progress. */
export function runningText(run, k) {
  const n = run.nSamples;
  if (n && isPlannedStep(run)) return t("panel.runningOfStep", { run: run.id, sample: k, samples: n });
  const key = n ? (run.signal ? "panel.runningOfAutomatic" : "panel.runningOf") : run.signal ? "panel.runningAutomatic" : "panel.running";
  return t(key, { run: run.id, sample: k, samples: n });
}

/**
 * How far the run is: samples taken of the declared number, the time left and
 * the planned end (RunOut.endsAt: START plus samples × dt in real time, so a
 * twin's speed-up is in it). Null for a run without a declared length.
 * @param {any} run  runspec.readRun
 * @param {number} taken  samples taken
 * @param {number} now  ms since the epoch
 */
export function runProgress(run, taken, now) {
  const n = run?.nSamples;
  if (!n) return null;
  const left = Math.max(0, n - taken);
  const ends = run.endsAt ? Date.parse(run.endsAt) : Number.NaN;
  const secondsLeft = Number.isFinite(ends) ? Math.max(0, (ends - now) / 1000) : left * run.dt;
  const end = Number.isFinite(ends) ? new Date(ends) : new Date(now + secondsLeft * 1000);
  return { taken: Math.min(taken, n), samples: n, secondsLeft, end };
}

/**
 * Show the progress of the panel's running run as an accessible bar (a native
 * <progress>: role progressbar with its values) with the time left and the end.
 * @param {{results: HTMLElement, progress?: any}} view
 * @param {any} run  the run, or null to hide the bar
 * @param {number} taken
 */
export function renderProgress(view, run, taken) {
  if (!view.progress) {
    const bar = h("progress", { "data-testid": "run-progress", "aria-label": t("panel.progressLabel") });
    const text = h("p", { class: "run-progress-text", "data-testid": "run-progress-text" });
    view.progress = { el: h("div", { class: "run-progress" }, bar, text), bar, text };
    view.results.before(view.progress.el);
  }
  const p = run && run.status === "running" ? runProgress(run, taken, Date.now()) : null;
  view.progress.el.hidden = !p;
  if (!p) return;
  const { bar, text } = view.progress;
  bar.max = p.samples;
  bar.value = p.taken;
  const words = { sample: p.taken, samples: p.samples, left: durationWords(p.secondsLeft), end: formatTime(p.end) };
  bar.setAttribute("aria-valuetext", t("panel.progressText", words));
  setText(text, t("panel.progressText", { ...words, left: duration(p.secondsLeft) }));
}

/** The run's timing in words (RunOut.timing): lateness for a real rig, exact for a twin. */
export function timingText(timing) {
  if (!timing || typeof timing !== "object") return "";
  if (timing.rig === "twin") return t("run.timingTwin");
  const s = (v) => formatQuantity(typeof v === "number" ? v : null, "seconds");
  return t("run.timingReal", { max: s(timing.maxLateness), p95: s(timing.p95Lateness), spread: formatQuantity(100 * (timing.periodSpread ?? 0), "percent") });
}

/**
 * The status line of a panel whose run ended, or that has had none (DOM
 * children: the server's end reason is its own sentence, see serverText).
 * @returns {Array<Node | string>}
 */
export function idleParts(run, panelId) {
  if (run && panelOfRun(run) === panelId) {
    const reason = endReasonNode(run.endReason);
    return reason !== null
      ? tParts("panel.endedWhy", { run: run.id, status: runStatusText(run.status), reason })
      : [t("panel.ended", { run: run.id, status: runStatusText(run.status) })];
  }
  return [t("panel.noRun")];
}

/** The status line of a panel while another panel's run is going. */
export function otherRunText(runPanel, number) {
  return t("panel.otherRun", { method: methodTitle(runPanel), panel: number ?? "?" });
}

/**
 * SRM's gain read from the last sample (the figure the paper's Table I prints
 * beside the settled gain), as a line under the gain; null for other methods.
 * @param {any} est
 */
export function lastSampleGain(est) {
  if (!est || !Number.isFinite(est.Klast)) return null;
  return h("span", { class: "hint figure-note", "data-field": "Klast" }, t("estimate.lastSample", { K: fmtFigure(est.Klast) }));
}

/**
 * Fill a panel's results with the estimates of `run` (null: the panel's methods, empty).
 * @param {{def: any, results: HTMLElement, operatingPoint: HTMLElement}} view
 * @param {any} run
 */
export function renderResults(view, run) {
  const found = run ? operatingPointsFound(run.methods.map(methodName), run.estimates) : [];
  // A run that identified another pair than u -> y says which (a kit's heater 2 -> sensor 2).
  const { input, output } = runPair(run);
  const pair = input !== "u" || output !== "y" ? t("panel.pairUsed", { pair: pairLabel(input, output) }) : "";
  setText(view.operatingPoint, [pair, operatingPointText(run?.operatingPoint), ...found].filter(Boolean).join(" "));
  view.operatingPoint.hidden = !view.operatingPoint.textContent;
  const asked = new Set(run ? run.methods.map(methodName) : []);
  const shown = view.def.methods.filter((m) => !(view.def.optional ?? []).includes(m) || asked.has(m));
  const rows = shown.map((m) => {
    const est = run?.estimates?.get(m) ?? null;
    return h(
      "tr",
      { "data-method": m, class: est && est.trusted === false ? "not-trusted" : null, "data-trusted": est ? String(est.trusted !== false) : null },
      h("th", { scope: "row" }, methodTitle(m)),
      h("td", { "data-field": "K" }, est ? fmtFigure(est.K) : "–", lastSampleGain(est)),
      h("td", { "data-field": "tau" }, est ? fmtFigure(est.tau) : "–"),
      h("td", { "data-field": "theta" }, est ? fmtFigure(est.theta) : "–"),
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
        h("thead", null, h("tr", null, col(t("table.method")), col(t("table.K")), col(t("table.tau")), col(t("table.theta")), col(t("table.atSample")), col(t("table.status")))),
        h("tbody", null, rows),
      ),
    ),
    ...[warningsList(shown, run?.estimates, run?.timing)].filter((w) => w !== null),
  );
}
