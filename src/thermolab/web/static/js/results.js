// @ts-check
// The figures of the paper's Tables I/II from a method's stored result.
//
// The lab computes them when a run ends, with the function thermolab identify
// prints a CSV record's with (thermolab.ident.table_figures), and returns them
// with the run (GET /api/runs/{run}, export.json): per method, `stats` holds
// mean / max / min of the valid estimates after convergence within ±1 % (or,
// where they never converge, their spread over the last 2000 samples) and the
// samples to converge. Nothing here recomputes them; a run that is still going
// has no statistics yet, only its latest estimate.

import { t } from "./i18n.js";

/**
 * @typedef {{mean: number, max: number, min: number}} Stat
 * @typedef {object} MethodFigures
 * @property {string} method
 * @property {{K: number | null, tau: number | null, theta: number | null, Klast: number | null,
 *   W: number[] | null}} final  the latest/final estimate (θ: dead time, s; Klast: SRM's last-sample gain)
 * @property {Stat | null} K       statistics (one value: mean = max = min)
 * @property {Stat | null} tau
 * @property {{K: number | null, tau: number | null}} convergedAt  samples to converge
 * @property {boolean} converges   whether the method's estimates can converge (one per sample or block)
 * @property {number | null} last  samples the statistics cover
 * @property {boolean} valid
 * @property {string | null} reason  why there is no first-order model
 * @property {string[]} warnings
 * @property {boolean} trusted  false when the library flags the model or it never converged
 *   (it never looks final then)
 * @property {boolean} converged  false when the server's count found no convergence
 * @property {{k: number[], K: number[], tau: number[]} | null} trajectory  for the charts
 */

const finite = (v) => typeof v === "number" && Number.isFinite(v);
const one = (v) => (finite(v) ? { mean: v, max: v, min: v } : null);

function stat(s) {
  if (!s || typeof s !== "object") return null;
  return finite(s.mean) && finite(s.max) && finite(s.min) ? { mean: s.mean, max: s.max, min: s.min } : null;
}

/**
 * @param {any} stored  {latest, final, error, estimates, trajectory?, stats?}
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
  const tr = s.trajectory;
  const trajectory =
    tr && Array.isArray(tr.k) && tr.k.length > 1
      ? { k: tr.k, K: tr.K.map((v) => (finite(v) ? v : Number.NaN)), tau: tr.tau.map((v) => (finite(v) ? v : Number.NaN)) }
      : null;
  const figures = s.stats && typeof s.stats === "object" ? s.stats : null;
  const conv = figures?.converged_at && typeof figures.converged_at === "object" ? figures.converged_at : null;
  return {
    method,
    final: {
      K: finite(latest.K) ? latest.K : null,
      tau: finite(latest.tau) ? latest.tau : null,
      theta: finite(extras.theta) ? extras.theta : null,
      Klast: finite(extras.K_last_sample) ? extras.K_last_sample : null,
      W: Array.isArray(latest.W) ? latest.W : null,
    },
    valid,
    reason: valid ? null : (extras.reason ?? s.error ?? (s.latest ? t("estimate.noModel") : t("estimate.none"))),
    warnings,
    // Estimates that never converged scatter (the paper's Table II): never a final model.
    converged: figures?.converged !== false,
    trusted: valid && figures?.converged !== false && (typeof extras.trusted === "boolean" ? extras.trusted : warnings.length === 0),
    // From the server once the run is over; while it runs, the latest estimate alone.
    K: figures ? stat(figures.K) : valid ? one(latest.K) : null,
    tau: figures ? stat(figures.tau) : valid ? one(latest.tau) : null,
    converges: conv !== null,
    convergedAt: { K: finite(conv?.K) ? conv.K : null, tau: finite(conv?.tau) ? conv.tau : null },
    last: finite(figures?.last) ? figures.last : null,
    trajectory,
  };
}
