// Reading a method's stored result (the `to_dict()` of thermolab.ident's
// result objects) into the figures of the paper's Tables I/II.

/**
 * @typedef {{mean: number, max: number, min: number}} Stat
 * @typedef {object} MethodFigures
 * @property {string} method
 * @property {Stat | null} K       one value: mean = max = min
 * @property {Stat | null} tau
 * @property {{K: number | null, tau: number | null}} convergedAt  samples to converge (recursive methods)
 * @property {boolean} valid
 * @property {string | null} reason  why there is no first-order model
 * @property {string[]} warnings
 * @property {{K: (number | null)[], tau: (number | null)[]} | null} trajectory
 */

const numOrNull = (v) => (typeof v === "number" && Number.isFinite(v) ? v : null);
const one = (v) => (numOrNull(v) === null ? null : { mean: v, max: v, min: v });

function stat(s) {
  if (!s || typeof s !== "object") return null;
  const mean = numOrNull(s.mean);
  if (mean === null) return null;
  return { mean, max: numOrNull(s.max) ?? mean, min: numOrNull(s.min) ?? mean };
}

/**
 * @param {any} result  a result dict (LSM, SRM, or a Trajectory's)
 * @param {string} [method]
 * @returns {MethodFigures}
 */
export function readResult(result, method) {
  const r = result && typeof result === "object" ? result : {};
  const m = String(method ?? r.method ?? "");
  if (r.stats && typeof r.stats === "object") {
    // A trajectory: statistics over the last samples, convergence, final estimate.
    const conv = r.converged_at ?? r.convergedAt ?? {};
    return {
      method: m,
      K: stat(r.stats.K),
      tau: stat(r.stats.tau),
      convergedAt: { K: numOrNull(conv.K), tau: numOrNull(conv.tau) },
      valid: Boolean(r.final?.valid ?? true),
      reason: r.final?.reason ?? null,
      warnings: Array.isArray(r.warnings) ? r.warnings.map(String) : [],
      trajectory: Array.isArray(r.K) && Array.isArray(r.tau) ? { K: r.K, tau: r.tau } : null,
      final: { K: numOrNull(r.final?.K), tau: numOrNull(r.final?.tau) },
    };
  }
  return {
    method: m,
    K: one(r.K),
    tau: one(r.tau),
    convergedAt: { K: null, tau: null },
    valid: r.valid !== false && numOrNull(r.K) !== null,
    reason: typeof r.reason === "string" ? r.reason : null,
    warnings: Array.isArray(r.warnings) ? r.warnings.map(String) : [],
    trajectory: null,
    final: { K: numOrNull(r.K), tau: numOrNull(r.tau) },
  };
}
