// @ts-check
// The closed loop's sentences in the reader's language: why a tuning rule
// cannot tune a model (a row of the tuning table), why a prediction may not
// hold (the note beside the measured figures) and why the adaptive tuner holds
// the gains. The server declares each once
// by a stable code (thermolab.control.words.LOOP_WORDS) and sends the code
// with its values beside its English sentence; here each code names its
// catalogue sentence and how each value is written for people. A sentence
// without a code, or of a code this page does not know, is shown as the
// server wrote it. tests/web/test_loopwords.py keeps LOOP_WORDS equal to the
// server's declaration.

import { h, serverText, tParts } from "./dom.js";
import { identWarning } from "./identwords.js";
import { formatNumber, t } from "./i18n.js";
import { formatQuantity } from "./quantities.js";

/** The codes of thermolab.control.words.LOOP_WORDS with their catalogue sentence. */
const LOOP_WORDS = [
  { code: "needs_dead_time", key: "loopWord.needsDeadTime" },
  { code: "gain_out_of_range", key: "loopWord.gainOutOfRange" },
  { code: "gain_size_out_of_range", key: "loopWord.gainSizeOutOfRange" },
  { code: "no_setpoint_recorded", key: "loopWord.noSetpointRecorded" },
  { code: "no_measured_step", key: "loopWord.noMeasuredStep" },
  { code: "no_model", key: "loopWord.noModel" },
  { code: "record_not_finite", key: "loopWord.recordNotFinite" },
  { code: "model_gain_invalid", key: "loopWord.modelGainInvalid" },
  { code: "model_tau_invalid", key: "loopWord.modelTauInvalid" },
  { code: "model_theta_invalid", key: "loopWord.modelThetaInvalid" },
  { code: "output_drifted", key: "loopWord.outputDrifted" },
  { code: "settling_near_band", key: "loopWord.settlingNearBand" },
  { code: "hold.no_estimate", key: "loopWord.holdNoEstimate" },
  { code: "hold.not_trusted", key: "loopWord.holdNotTrusted" },
  { code: "hold.not_tunable", key: "loopWord.holdNotTunable" },
  { code: "hold.wrong_sign", key: "loopWord.holdWrongSign" },
  { code: "hold.unsettled_invalid", key: "loopWord.holdUnsettledInvalid" },
  { code: "hold.unsettled_moved", key: "loopWord.holdUnsettledMoved" },
  { code: "hold.little_excitation", key: "loopWord.holdLittleExcitation" },
];

const KEYS = new Map(LOOP_WORDS.map((w) => [w.code, w.key]));
/** The gains as the table's heads name them. */
const GAIN_KEYS = { kp: "loop.kp", ti: "loop.ti", td: "loop.td" };

/** @param {unknown} v */
function figure(v) {
  return typeof v === "number" && Number.isFinite(v) ? formatNumber(v, { maximumSignificantDigits: 4 }).replace(/^-/, "−") : "–";
}

/** @param {unknown} v  a change, written with its sign */
function signed(v) {
  return typeof v === "number" && Number.isFinite(v) ? formatNumber(v, { maximumSignificantDigits: 3, signDisplay: "exceptZero" }).replace(/^-/, "−") : "–";
}

/** @param {unknown} v @param {import("./quantities.js").Quantity} kind */
function quantity(v, kind) {
  return typeof v === "number" ? formatQuantity(v, kind) : "–";
}

/**
 * How each value of a sentence is written: a rule as the table names it, a
 * gain by the table's head, percentages and seconds by their rule, the rest as figures.
 * @type {Record<string, (v: unknown) => Node | string>}
 */
const WRITE = {
  rule: (v) => String(v).toUpperCase(),
  gain: (v) => {
    const key = GAIN_KEYS[/** @type {keyof typeof GAIN_KEYS} */ (String(v))];
    return key ? t(key) : String(v);
  },
  value: figure,
  low: figure,
  high: figure,
  slope: signed,
  away: signed,
  theta: (v) => quantity(v, "seconds"),
  measured: (v) => quantity(v, "percent"),
  predicted: (v) => quantity(v, "percent"),
  band: (v) => quantity(v, "percent"),
  every: figure,
  moved: figure,
  tolerance: (v) => quantity(v, "percent"),
  share: (v) => quantity(v, "percent"),
  // The estimate's figure that moved, by its symbol.
  name: (v) => (v === "tau" ? "τ" : String(v)),
  // An identification warning, in words by its kind (identwords.js).
  warning: (v) => identWarning(String(v)),
  // The tuning's own English reason.
  reason: (v) => serverText(String(v)),
};

/**
 * A sentence of the closed loop in the reader's language, from its code and
 * values; without a known code, the server's English as it wrote it.
 * @param {{ code?: string, params?: Record<string, unknown> } | null | undefined} word
 * @param {string} english  the server's sentence
 * @returns {Node | string}
 *
 * @example loopWord({ code: "needs_dead_time", params: { rule: "zn" } }, "rule 'zn' needs…") // pt-BR "ZN precisa de um tempo morto θ > 0; …"
 */
export function loopWord(word, english) {
  const key = word?.code ? KEYS.get(word.code) : undefined;
  if (!key || !word) return serverText(String(english));
  /** @type {Record<string, Node | string>} */
  const params = {};
  for (const [name, value] of Object.entries(word.params ?? {})) params[name] = (WRITE[name] ?? figure)(value);
  return h("span", { "data-code": word.code }, ...tParts(key, params));
}

/**
 * The notes of a prediction, each in the reader's language, joined as the server joins them.
 * @param {Array<{ code?: string, params?: Record<string, unknown> }> | undefined} notes
 * @param {string} english  the server's `note`
 * @returns {Array<Node | string>}
 */
export function loopNotes(notes, english) {
  if (!Array.isArray(notes) || notes.length === 0) return [serverText(english)];
  if (notes.some((n) => !n?.code || !KEYS.has(n.code))) return [serverText(english)];
  return notes.flatMap((n, i) => (i ? ["; ", loopWord(n, english)] : [loopWord(n, english)]));
}
