// The figures of the paper's Tables I/II from a method's stored result.
//
// The lab stores, per method, the latest (or final) estimate and the whole
// trajectory of estimates (`k`, `K`, `tau`, `valid`: GET /api/runs/{run}/export.json).
// The statistics follow the paper and thermolab.ident.Trajectory: mean, max
// and min over the valid estimates of the last 2000 samples; the stabilisation
// value is that mean; samples to converge is the first sample index after
// which every estimate is valid and within ±1 % of it.

/** Samples the statistics are taken over (the paper's "last 2000 samples"). */
export const LAST = 2000;
/** Relative band of convergence (the paper's ±1 %). */
export const TOL = 0.01;

/**
 * @typedef {{mean: number, max: number, min: number}} Stat
 * @typedef {object} MethodFigures
 * @property {string} method
 * @property {{K: number | null, tau: number | null}} final   the latest/final estimate
 * @property {Stat | null} K       statistics (one value: mean = max = min)
 * @property {Stat | null} tau
 * @property {{K: number | null, tau: number | null}} convergedAt  samples to converge
 * @property {boolean} valid
 * @property {string | null} reason  why there is no first-order model
 * @property {string[]} warnings
 * @property {{k: number[], K: number[], tau: number[]} | null} trajectory
 */

const finite = (v) => typeof v === "number" && Number.isFinite(v);
const one = (v) => (finite(v) ? { mean: v, max: v, min: v } : null);

/**
 * @param {any} stored  {latest, final, error, estimates, trajectory?}
 * @param {string} method
 * @returns {MethodFigures}
 */
export function readResult(stored, method) {
  const s = stored && typeof stored === "object" ? stored : {};
  const latest = s.latest && typeof s.latest === "object" ? s.latest : {};
  const extras = latest.extras && typeof latest.extras === "object" ? latest.extras : {};
  const warnings = [
    ...(Array.isArray(extras.warnings) ? extras.warnings.map(String) : []),
    ...(s.error ? [String(s.error)] : []),
  ];
  const valid = latest.valid === true && finite(latest.K) && finite(latest.tau);
  const base = {
    method,
    final: { K: finite(latest.K) ? latest.K : null, tau: finite(latest.tau) ? latest.tau : null },
    valid,
    reason: valid ? null : (extras.reason ?? s.error ?? (s.latest ? "no first-order model" : "no estimate")),
    warnings,
  };
  const tr = s.trajectory;
  if (tr && Array.isArray(tr.k) && tr.k.length > 1) {
    const k = tr.k;
    const K = tr.K.map((v) => (finite(v) ? v : Number.NaN));
    const tau = tr.tau.map((v) => (finite(v) ? v : Number.NaN));
    const ok = k.map((_, i) => tr.valid?.[i] !== false && finite(K[i]) && finite(tau[i]));
    const from = k[k.length - 1] - LAST; // estimates of the last LAST samples: k > from
    const KStat = tailStats(k, K, ok, from);
    const tauStat = tailStats(k, tau, ok, from);
    return {
      ...base,
      K: KStat,
      tau: tauStat,
      convergedAt: {
        K: KStat ? firstSettled(k, K, ok, KStat.mean) : null,
        tau: tauStat ? firstSettled(k, tau, ok, tauStat.mean) : null,
      },
      trajectory: { k, K, tau },
    };
  }
  return {
    ...base,
    K: valid ? one(latest.K) : null,
    tau: valid ? one(latest.tau) : null,
    convergedAt: { K: null, tau: null },
    trajectory: null,
  };
}

function tailStats(k, v, ok, from) {
  let n = 0;
  let sum = 0;
  let max = -Infinity;
  let min = Infinity;
  for (let i = 0; i < k.length; i += 1) {
    if (k[i] <= from || !ok[i]) continue;
    n += 1;
    sum += v[i];
    if (v[i] > max) max = v[i];
    if (v[i] < min) min = v[i];
  }
  return n ? { mean: sum / n, max, min } : null;
}

/** The sample index after which every estimate is valid and within ±TOL of `target`. */
function firstSettled(k, v, ok, target) {
  const band = Math.abs(target) * TOL;
  let at = null;
  for (let i = k.length - 1; i >= 0; i -= 1) {
    if (!ok[i] || !(Math.abs(v[i] - target) <= band)) break;
    at = k[i];
  }
  return at;
}
