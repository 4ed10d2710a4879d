// @ts-check
// The identification library's sentences in the reader's language. Every
// warning starts with its kind, then a colon ("implausible gain: K = -1 has
// the wrong sign"; a trajectory's check of its final estimate adds "final
// estimate: " in front), and thermolab.ident.advice.ADVICE declares each kind
// once with what it means and what to do. A warning of a kind below reads as
// its kind's name and that advice in the page's language, the library's
// detail after them (numbers and symbols, marked as English); so does an
// estimate's reason why there is no model, by the kinds the methods give. A
// sentence of a kind this page does not know is shown as the server wrote it.
// tests/web/test_identwords.py keeps WARNING_KINDS equal to ADVICE.

import { h, serverText, tParts } from "./dom.js";
import { t } from "./i18n.js";

/** The warning kinds of thermolab.ident.advice.ADVICE, with their name and advice. */
const WARNING_KINDS = [
  { kind: "residual test failed", name: "warningKind.residualTestFailed", advice: "warningAdvice.residualTestFailed" },
  { kind: "implausible time constant", name: "warningKind.implausibleTimeConstant", advice: "warningAdvice.implausibleTimeConstant" },
  { kind: "implausible gain", name: "warningKind.implausibleGain", advice: "warningAdvice.implausibleGain" },
  { kind: "timing jitter", name: "warningKind.timingJitter", advice: "warningAdvice.timingJitter" },
  { kind: "gap in time", name: "warningKind.gapInTime", advice: "warningAdvice.gapInTime" },
  { kind: "estimates across a gap", name: "warningKind.estimatesAcrossAGap", advice: "warningAdvice.estimatesAcrossAGap" },
  { kind: "operating point undetermined", name: "warningKind.operatingPointUndetermined", advice: "warningAdvice.operatingPointUndetermined" },
  { kind: "constant term poorly determined", name: "warningKind.constantTermPoorlyDetermined", advice: "warningAdvice.constantTermPoorlyDetermined" },
  { kind: "the optimiser did not converge", name: "warningKind.optimiserDidNotConverge", advice: "warningAdvice.optimiserDidNotConverge" },
  { kind: "no 63.2% crossing", name: "warningKind.no632Crossing", advice: "warningAdvice.no632Crossing" },
  { kind: "small step", name: "warningKind.smallStep", advice: "warningAdvice.smallStep" },
  { kind: "short record", name: "warningKind.shortRecord", advice: "warningAdvice.shortRecord" },
  { kind: "moving before the step", name: "warningKind.movingBeforeTheStep", advice: "warningAdvice.movingBeforeTheStep" },
  { kind: "no sound fit", name: "warningKind.noSoundFit", advice: "warningAdvice.noSoundFit" },
  { kind: "poor fit", name: "warningKind.poorFit", advice: "warningAdvice.poorFit" },
  { kind: "not settled", name: "warningKind.notSettled", advice: "warningAdvice.notSettled" },
];

/**
 * Why an estimate has no model, by the kind its sentence starts with: the
 * methods' errors (ident/_step_detect.py, _validation.py, step.py, oe.py) and
 * a trajectory's reasons (ident/models.py INVALID_REASONS).
 */
const REASON_KINDS = [
  { kind: "no step", name: "reasonKind.noStep" },
  { kind: "no excitation", name: "reasonKind.noExcitation" },
  { kind: "too few samples", name: "reasonKind.tooFewSamples" },
  { kind: "too few samples after the step", name: "reasonKind.tooFewSamplesAfterTheStep" },
  { kind: "no estimate yet", name: "reasonKind.noEstimateYet" },
  { kind: "not excited", name: "reasonKind.notExcited" },
  { kind: "unstable or integrating model", name: "reasonKind.unstableOrIntegrating" },
  { kind: "dominant pole <= 0", name: "reasonKind.nonPositivePole" },
  { kind: "dominant pole is complex", name: "reasonKind.complexPole" },
  { kind: "non-finite estimate", name: "reasonKind.nonFinite" },
];

const WARNINGS = new Map(WARNING_KINDS.map((w) => [w.kind, w]));
const REASONS = new Map(REASON_KINDS.map((r) => [r.kind, r]));
/** The prefix of a trajectory's check of its final estimate (ident.advice.warning_kind). */
const FINAL = /^final estimate: /;

/**
 * A sentence's kind (its text before the first colon) and detail (after it).
 * @param {string} text
 */
function split(text) {
  const colon = text.indexOf(":");
  if (colon < 0) return { kind: text.trim(), detail: "" };
  return { kind: text.slice(0, colon).trim(), detail: text.slice(colon + 1).trim() };
}

/**
 * The library's detail, marked as English; none when it is empty.
 * @param {string} detail
 */
function detailNode(detail) {
  return detail ? serverText(detail) : "";
}

/**
 * A warning of the identification library in the reader's language: its
 * kind's name and advice, then its detail (marked as English); a warning of
 * an unknown kind as the server wrote it.
 * @param {string} warning
 * @returns {Node | string}
 *
 * @example identWarning("short record: 40 samples") // pt-BR "registro curto: … (40 samples)"
 */
export function identWarning(warning) {
  const text = String(warning);
  const final = FINAL.test(text);
  const { kind, detail } = split(text.replace(FINAL, ""));
  const known = WARNINGS.get(kind);
  if (!known) return serverText(text);
  const key = detail ? "identWords.warning" : "identWords.warningNoDetail";
  const said = h("span", { "data-kind": kind }, ...tParts(key, { kind: t(known.name), advice: t(known.advice), detail: detailNode(detail) }));
  return final ? h("span", null, ...tParts("identWords.finalEstimate", { warning: said })) : said;
}

/**
 * Why an estimate has no model in the reader's language: the reason's kind in
 * words, then its detail (marked as English); an unknown reason as the server wrote it.
 * @param {string} reason
 * @returns {Node | string}
 */
export function identReason(reason) {
  const text = String(reason);
  const { kind, detail } = split(text);
  const known = REASONS.get(kind);
  if (!known) return serverText(text);
  const name = t(known.name);
  return detail ? h("span", { "data-kind": kind }, ...tParts("identWords.reason", { kind: name, detail: detailNode(detail) })) : h("span", { "data-kind": kind }, name);
}
