// @ts-check
// Numbers for people: one rule per kind of quantity a student reads (how
// finely it is known, so how many decimals say it), in the language's form,
// never in scientific notation and never with the float noise of a binary
// fraction (0.1 + 0.2). Model figures compared digit by digit with the paper
// keep their own rule (model.js fmtFigure: six decimals).

import { formatNumber } from "./i18n.js";

/**
 * The rules: at most `decimals` decimals (trailing zeros dropped), so a value
 * smaller than half the last one reads 0.
 * - volts: the box's input and output, read to 1 mV (the converter's step is ~2.4 mV);
 * - seconds: times and periods, to 1 ms (the lab's clock does not keep better);
 * - hertz: a signal's frequency, to 0.1 mHz (the Automatic wave is 1/(10 T));
 * - percent: shares, spreads and a heater's level, to 0.1 %;
 * - celsius: a kit's temperatures, to 0.01 °C (its sensors' step is ~0.3 °C, its readings have two decimals);
 * - factor: dimensionless settings (γ, pmax), to 6 decimals (γ = 0.999999 is a choice);
 * - reading: a rig's channel in a unit with no rule of its own, to 3 decimals.
 */
export const QUANTITY_RULES = Object.freeze({
  volts: { decimals: 3 },
  seconds: { decimals: 3 },
  hertz: { decimals: 4 },
  percent: { decimals: 1 },
  celsius: { decimals: 2 },
  factor: { decimals: 6 },
  reading: { decimals: 3 },
});

/** @typedef {keyof typeof QUANTITY_RULES} Quantity */

/**
 * A value of `kind` in the reader's language, without its unit; "–" when missing.
 * @param {number | null | undefined} value
 * @param {Quantity} kind
 * @returns {string}
 *
 * @example formatQuantity(2.29665e-26, "volts") // "0"
 * @example formatQuantity(250.12623300000004, "seconds") // "250.126" ("250,126" in pt-BR)
 */
export function formatQuantity(value, kind) {
  if (value === null || value === undefined || !Number.isFinite(value)) return "–";
  const { decimals } = QUANTITY_RULES[kind];
  // Rounded first, so that −0.0001 V reads 0 rather than −0.
  const rounded = Number(value.toFixed(decimals)) || 0;
  return formatNumber(rounded, { useGrouping: false, maximumFractionDigits: decimals }).replace(/^-/, "−");
}

/** @type {Readonly<Record<string, Quantity>>} The rule of each unit a rig declares its channels in. */
const QUANTITY_OF_UNIT = Object.freeze({ V: "volts", s: "seconds", "%": "percent", degC: "celsius", "°C": "celsius" });

/** @type {Readonly<Record<string, string>>} How a unit a rig declares is written for people (the rigs write °C as "degC"). */
const UNIT_SYMBOLS = Object.freeze({ degC: "°C" });

/**
 * The rule for a channel in `unit` (volts for V, percent for %, celsius for °C, else reading).
 * @param {string} unit  as the rig declares it
 * @returns {Quantity}
 */
export function quantityOfUnit(unit) {
  return QUANTITY_OF_UNIT[unit] ?? "reading";
}

/**
 * A unit as a person reads it.
 * @param {string} unit  as the rig declares it
 * @returns {string}
 *
 * @example unitSymbol("degC") // "°C"
 * @example unitSymbol("%") // "%"
 */
export function unitSymbol(unit) {
  return UNIT_SYMBOLS[unit] ?? unit;
}
