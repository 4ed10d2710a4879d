// @ts-check
// First-order model arithmetic for display: the discrete form of eq. 4, the
// prediction drawn over the data, and the figures of the paper's Tables I/II.
// The identification itself happens on the server; nothing here estimates.

import { decimalMark, formatNumber } from "./i18n.js";

/** The paper's reference model, eq. 16 (step method on the real rig, T = 1 s). */
export const REFERENCE_MODEL = Object.freeze({ K: 0.14009, tau: 250.126233 });

/** The paper's initial WLSM parameters W0 = [a, b] (Ks = 0.0269905, Ts = 26.73742 s). */
export const PAPER_W0 = Object.freeze({ a: 0.96329, b: 9.9082e-4 });

/**
 * Discrete parameters of K/(tau s + 1) sampled with a zero-order hold at dt.
 * @returns {{a: number, b: number}}
 */
export function toDiscrete(K, tau, dt) {
  const a = Math.exp(-dt / tau);
  return { a, b: (1 - a) * K };
}

/**
 * Continuous parameters from the discrete ones; null where the discrete model
 * has no first-order meaning (a outside (0, 1)).
 * @returns {{K: number, tau: number} | null}
 */
export function fromDiscrete(a, b, dt) {
  if (!(a > 0 && a < 1) || !Number.isFinite(b) || !(dt > 0)) return null;
  return { K: b / (1 - a), tau: -dt / Math.log(a) };
}

/**
 * The model's free-run response to the recorded input about the level y0 (the
 * equilibrium at 0 V: the run's first output for the identification's default
 * "initial" offset, else see predictionBase), so yhat[k] = y0 + x[k] with
 * x[k+1] = a x[k] + b u[k − d], d the model's dead time θ in samples (to the
 * nearest; 0 without θ). `x0` is the state at the first sample given: 0
 * when `u` starts at the run's first sample of a run from rest, else the
 * measured y minus y0 there. Before the record the input is taken as off for
 * a start at rest and as the first input otherwise.
 * @param {ArrayLike<number>} u
 * @param {number} y0
 * @param {{K: number, tau: number, theta?: number}} model
 * @param {number} dt
 * @param {Float64Array} [out] reused when long enough
 * @param {number} [x0]
 */
export function predict(u, y0, model, dt, out, x0 = 0) {
  const n = u.length;
  const y = out && out.length >= n ? out.subarray(0, n) : new Float64Array(n);
  if (n === 0) return y;
  const { a, b } = toDiscrete(model.K, model.tau, dt);
  let x = Number.isFinite(x0) ? x0 : 0;
  const theta = model.theta ?? 0;
  const d = Number.isFinite(theta) && theta > 0 ? Math.round(theta / dt) : 0;
  const before = x === 0 ? 0 : u[0];
  for (let k = 0; k < n; k += 1) {
    y[k] = y0 + x;
    const uk = k >= d ? u[k - d] : before;
    x = a * x + b * (Number.isFinite(uk) ? uk : 0);
  }
  return y;
}

/**
 * The level the model's response is drawn about, from how the run treated the
 * operating point (RunOut.operatingPoint.used): "initial" (the default) takes
 * the run's first output as the equilibrium at 0 V; "fit" estimated a
 * constant term c with the model, W = [a, b, c], whose equilibrium at 0 V is
 * c / (1 − a); "none" is the raw regression (0 V); a number is the known
 * ambient output. Draw with predict(u, base, model, dt, out, y0 − base).
 * @param {string | number | null | undefined} used
 * @param {number[] | null | undefined} W  the estimate's discrete parameters
 * @param {number} y0  the run's first output
 */
export function predictionBase(used, W, y0) {
  if (typeof used === "number" && Number.isFinite(used)) return used;
  if (used === "none") return 0;
  // "auto" left it to the data: a constant term in W means the method chose "fit".
  if ((used === "fit" || used === "auto") && W && W.length === 3) {
    const [a, , c] = W;
    if (a > 0 && a < 1 && Number.isFinite(c)) return c / (1 - a);
  }
  return y0;
}

/** Absolute and relative deviation of a value from a reference. */
export function deviation(value, reference) {
  if (!Number.isFinite(value) || !Number.isFinite(reference)) return null;
  const d = value - reference;
  return { abs: d, rel: reference === 0 ? Number.NaN : d / reference };
}

/**
 * Format a number for a table cell with `digits` significant digits; an
 * en dash for missing values.
 */
export function fmt(v, digits = 6) {
  if (v === null || v === undefined || !Number.isFinite(v)) return "–";
  if (v === 0) return "0";
  const mag = Math.abs(v);
  // In the current language's form (decimal comma in pt-BR), without grouping:
  // table cells are read digit by digit against the paper's values.
  if (mag >= 1e6 || mag < 1e-4) return v.toExponential(Math.max(0, digits - 1)).replace(".", decimalMark());
  return formatNumber(Number(v.toPrecision(digits)), { useGrouping: false, maximumFractionDigits: 20 });
}

/** Decimals the paper's Tables I/II print Ks and Ts with (0.140090, 250.126233). */
export const FIGURE_DECIMALS = 6;

/**
 * A model parameter (Ks, Ts, θ, their statistics) as the paper's tables print
 * it: six decimals, so the page reads digit by digit against Table I and
 * `thermolab reproduce table1` (fmt's six significant digits would cut
 * 250.126233 to 250.126).
 * @param {number | null | undefined} v
 */
export function fmtFigure(v) {
  if (v === null || v === undefined || !Number.isFinite(v)) return "–";
  // Never in scientific notation, where a student reads it: a huge figure (a model
  // that did not fit) to six significant digits, a tiny one as the six decimals
  // give it (θ = 6.6e-11 s is 0.000000, no dead time).
  if (Math.abs(v) >= 1e6) return formatNumber(Number(v.toPrecision(6)), { useGrouping: false, maximumFractionDigits: 0 });
  const rounded = Number(v.toFixed(FIGURE_DECIMALS)) || 0;
  return formatNumber(rounded, { useGrouping: false, minimumFractionDigits: FIGURE_DECIMALS, maximumFractionDigits: FIGURE_DECIMALS });
}

/**
 * A figure's deviation from its reference, to the figures' six decimals with
 * trailing zeros dropped and a sign ("+0.0021", "−0.5"); "0" when it is below
 * the last decimal (−3.062e-9 is no deviation at the precision the tables print).
 * @param {number | null | undefined} d
 */
export function fmtDeviation(d) {
  if (d === null || d === undefined || !Number.isFinite(d)) return "–";
  if (Math.abs(d) >= 1e6) return fmt(d);
  const rounded = Number(d.toFixed(FIGURE_DECIMALS));
  if (rounded === 0) return "0";
  return formatNumber(rounded, { useGrouping: false, maximumFractionDigits: FIGURE_DECIMALS, signDisplay: "always" }).replace("-", "−");
}

/**
 * A relative deviation in percent, to two decimals ("−1.25 %"), "0 %" below them.
 * @param {number | null | undefined} rel  the deviation over the reference
 */
export function fmtPercentDeviation(rel) {
  if (rel === null || rel === undefined || !Number.isFinite(rel)) return "–";
  const rounded = Number((100 * rel).toFixed(2));
  if (rounded === 0) return "0 %";
  return `${formatNumber(rounded, { useGrouping: false, maximumFractionDigits: 2, signDisplay: "always" }).replace("-", "−")} %`;
}
