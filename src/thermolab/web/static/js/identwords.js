// @ts-check
// The identification library's sentences in the reader's language. Every
// warning starts with its kind, then a colon ("implausible gain: K = -1 has
// the wrong sign"; a trajectory's check of its final estimate adds "final
// estimate: " in front), and thermolab.ident.advice.ADVICE declares each kind
// once with what it means and what to do. A warning of a kind below reads as
// its kind's name and that advice in the page's language, then its detail:
// the sentence's code and figures are read back with the patterns of
// thermolab.ident.notes (identnotes.js, written from them) and said by the
// catalogue's "identNote.<code>" in the page's language, its figures with the
// language's decimal mark; a sentence no pattern reads keeps the library's
// detail, marked as English. An estimate's reason why there is no model reads
// the same way. A sentence of no kind that a pattern reads whole (why an
// estimate is not trusted) is said by its catalogue sentence; any other
// sentence of a kind this page does not know is shown as the server wrote it. tests/web/test_identwords.py keeps WARNING_KINDS equal to
// ADVICE and the catalogue's notes equal to NOTES.

import { h, serverText, tParts } from "./dom.js";
import { formatNumber, t } from "./i18n.js";
import { NOTE_PATTERNS } from "./identnotes.js";

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
  { kind: "final estimate not excited", name: "warningKind.finalEstimateNotExcited", advice: "warningAdvice.finalEstimateNotExcited" },
  { kind: "dead time ambiguous", name: "warningKind.deadTimeAmbiguous", advice: "warningAdvice.deadTimeAmbiguous" },
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

const NOTES = NOTE_PATTERNS.map((note) => ({ ...note, regexp: new RegExp(note.pattern, "s") }));
/** A figure as the library wrote it: "0.14", "-3.2e-05", "+1.50". */
const FIGURE = /[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?/gi;
/** Fields the library copies from elsewhere (the optimiser's own words): kept as written. */
const VERBATIM = new Set(["message"]);

/**
 * The code and fields of a sentence (kind included), or null when no pattern reads it.
 * @param {string} text
 * @returns {{code: string, fields: Record<string, string>} | null}
 */
export function readNote(text) {
  for (const note of NOTES) {
    const found = note.regexp.exec(text);
    if (found) return { code: note.code, fields: Object.fromEntries(note.fields.map((name, i) => [name, found[i + 1]])) };
  }
  return null;
}

/**
 * The figures of a field in the reader's language, with the digits the library gave
 * them ("0.140" reads "0,14" in pt-BR; a unit after a figure stays).
 * @param {string} text
 *
 * @example localFigures("-0.5 °C") // pt-BR "-0,5 °C"
 */
export function localFigures(text) {
  return text.replace(FIGURE, (figure) => {
    const value = Number(figure);
    if (!Number.isFinite(value)) return figure;
    const mantissa = figure.replace(/^[-+]/, "").split(/e/i)[0].replace(".", "").replace(/^0+/, "");
    const far = value !== 0 && (Math.abs(value) < 1e-3 || Math.abs(value) >= 1e9);
    return formatNumber(value, {
      maximumSignificantDigits: Math.min(21, Math.max(1, mantissa.length)),
      notation: far ? "scientific" : "standard",
      signDisplay: figure.startsWith("+") ? "exceptZero" : "auto",
      useGrouping: false,
    });
  });
}

/** "residual_dead_time" -> "identNote.residualDeadTime". @param {string} code */
function noteKey(code) {
  return `identNote.${code.replace(/_([a-z])/g, (_, c) => c.toUpperCase())}`;
}

/**
 * A sentence's detail in the reader's language when a pattern reads it, else the
 * library's detail marked as English; none when it is empty.
 * @param {string} text  the whole sentence (its kind included)
 * @param {string} detail  the library's words after the kind
 * @returns {Node | string}
 */
function detailNode(text, detail) {
  const note = readNote(text);
  if (!note) return detail ? serverText(detail) : "";
  /** @type {Record<string, Node | string>} */
  const params = {};
  for (const [name, value] of Object.entries(note.fields)) params[name] = VERBATIM.has(name) ? serverText(value) : localFigures(value);
  return h("span", { "data-note": note.code }, ...tParts(noteKey(note.code), params));
}

/**
 * A sentence of no warning kind that a note's pattern reads whole (why an estimate
 * is not trusted: "poor free-run fit: …"), said by its catalogue sentence, kind
 * included; null when no pattern reads it.
 * @param {string} text
 * @returns {Node | null}
 */
function wholeNote(text) {
  const note = readNote(text);
  if (!note) return null;
  /** @type {Record<string, Node | string>} */
  const params = {};
  for (const [name, value] of Object.entries(note.fields)) params[name] = VERBATIM.has(name) ? serverText(value) : localFigures(value);
  // Why there is no model ("no model: no step: …"): a reason of its own.
  if (note.fields.reason !== undefined) params.reason = identReason(note.fields.reason);
  return h("span", { "data-note": note.code }, ...tParts(noteKey(note.code), params));
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
  const body = text.replace(FINAL, "");
  const { kind, detail } = split(body);
  const known = WARNINGS.get(kind);
  if (!known) return wholeNote(body) ?? serverText(text);
  const key = detail ? "identWords.warning" : "identWords.warningNoDetail";
  const said = h("span", { "data-kind": kind }, ...tParts(key, { kind: t(known.name), advice: t(known.advice), detail: detailNode(body, detail) }));
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
  return detail ? h("span", { "data-kind": kind }, ...tParts("identWords.reason", { kind: name, detail: detailNode(text, detail) })) : h("span", { "data-kind": kind }, name);
}
