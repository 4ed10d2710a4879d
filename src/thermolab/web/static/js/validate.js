// @ts-check
// Client-side checks of numeric fields, before anything is sent. The server
// checks again (it is the authority); these only spare a round trip and say
// exactly what is allowed next to the field.

import { formatDecimal, t } from "./i18n.js";

/**
 * @typedef {object} FieldSpec
 * @property {string} label   what the field is, for messages
 * @property {number} min
 * @property {number} max
 * @property {boolean} [integer]
 * @property {boolean} [exclusiveMin]  min itself not allowed (γ > 0 ...)
 * @property {boolean} [exclusiveMax]
 * @property {string} [unit]
 */

/** Text of the allowed range, e.g. "−10 to 10 V" or "an integer from 10 to 100000". */
export function rangeText(spec) {
  const unit = spec.unit ? ` ${spec.unit}` : "";
  const min = num(spec.min);
  const max = spec.max === undefined ? "" : num(spec.max);
  const whole = (range) => (spec.integer ? t("range.integer", { range }) : range);
  const hi = t(spec.exclusiveMax ? "range.lessThan" : "range.atMost", { max });
  const unbounded = (v) => v === undefined || v === null || v === Infinity || v === -Infinity;
  // No lower bound (a set point below the output limit): say only the upper one, never "−∞".
  if (unbounded(spec.min)) return unbounded(spec.max) ? whole(t("range.any")) : whole(hi) + unit;
  const lo = t(spec.exclusiveMin ? "range.moreThan" : "range.atLeast", { min });
  // A bound no one reaches (a run number's 2^53) is no bound for the reader: "at least 1".
  if (unbounded(spec.max) || spec.max >= Number.MAX_SAFE_INTEGER) return whole(lo) + unit;
  if (!spec.exclusiveMin && !spec.exclusiveMax) {
    return t(spec.integer ? "range.integerBetween" : "range.between", { min, max }) + unit;
  }
  return whole(t("range.both", { lo, hi })) + unit;
}

function num(v) {
  // The language's decimal mark, and a true minus sign (it reads better and
  // screen readers say "minus").
  return formatDecimal(v);
}

/**
 * The number a person typed, in plain decimal notation: a decimal comma
 * (pt-BR, es: "0,96") or point is the decimal mark in any language, since a
 * student types what their keyboard and habit give; a leading "−" is a minus.
 * Grouped thousands ("1.000,5", "1,000.5") carry two marks and are refused
 * rather than guessed at, as are "0x10" and "" (which Number() would accept).
 * @param {string} text
 * @returns {number | null}  null when the text is not a number
 *
 * @example parseDecimal("0,96") // 0.96
 */
export function parseDecimal(text) {
  const cleaned = String(text).trim().replace(/^−/, "-").replace(",", ".");
  if (!/^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$/.test(cleaned)) return null;
  return Number(cleaned);
}

/**
 * Parse and check one field's text.
 * @param {string} text
 * @param {FieldSpec} spec
 * @returns {{ok: true, value: number} | {ok: false, error: string}}
 */
export function checkNumber(text, spec) {
  if (String(text).trim() === "") return { ok: false, error: t("check.required", { label: spec.label, range: rangeText(spec) }) };
  const v = parseDecimal(text);
  if (v === null) {
    return { ok: false, error: t("check.notNumber", { label: spec.label, range: rangeText(spec) }) };
  }
  if (!Number.isFinite(v)) {
    return { ok: false, error: t("check.notFinite", { label: spec.label, range: rangeText(spec) }) };
  }
  if (spec.integer && !Number.isInteger(v)) {
    return { ok: false, error: t("check.notWhole", { label: spec.label, range: rangeText(spec) }) };
  }
  const belowMin = spec.exclusiveMin ? v <= spec.min : v < spec.min;
  const max = spec.max ?? Infinity;
  const aboveMax = spec.exclusiveMax ? v >= max : v > max;
  if (belowMin || aboveMax) {
    return { ok: false, error: t("check.outOfRange", { label: spec.label, range: rangeText(spec), value: num(v) }) };
  }
  return { ok: true, value: v };
}

/**
 * Check several fields at once.
 * @param {Record<string, string>} texts
 * @param {Record<string, FieldSpec>} specs
 * @returns {{values: Record<string, number>, errors: Record<string, string>}}
 */
export function checkAll(texts, specs) {
  /** @type {Record<string, number>} */
  const values = {};
  /** @type {Record<string, string>} */
  const errors = {};
  for (const [name, spec] of Object.entries(specs)) {
    const r = checkNumber(texts[name] ?? "", spec);
    if (r.ok) values[name] = r.value;
    else errors[name] = r.error;
  }
  return { values, errors };
}
