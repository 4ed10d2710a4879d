// Runs: the body of POST /api/rigs/{rig}/runs built from a panel, and the run
// objects of GET /api/runs/{run} read into one shape for the views.

const METHOD_TITLES = {
  srm: "Step response (SRM)",
  lsm: "Least squares (LSM)",
  blockls: "Block least squares",
  malsm: "Moving-window LS (MALSM)",
  wlsm: "Weighted LS (WLSM)",
};

/** Methods whose estimates form a trajectory (Ks(k), Ts(k) charts). */
export const RECURSIVE = new Set(["blockls", "malsm", "wlsm"]);

export function methodTitle(method) {
  if (method === "srm-lsm") return "step response + least squares";
  return METHOD_TITLES[method] ?? String(method);
}

/** The square wave of the Automatic option: ten times slower than sampling. */
export function automaticSignal(low, high, dt) {
  const freq = 1 / (10 * dt);
  return `square:${low}:${high}:${Number(freq.toPrecision(12))}`;
}

/**
 * The body of POST /api/rigs/{rig}/runs for a panel's checked values.
 * @param {{id: string}} panel
 * @param {Record<string, number>} v  checked values (dt, n, setpoint | low/high, window, gamma, pmax, a0, b0)
 * @param {boolean} automatic
 */
export function buildRunSpec(panel, v, automatic) {
  const spec = { dt: v.dt, n_samples: v.n };
  if (automatic) spec.signal = automaticSignal(v.low, v.high, v.dt);
  else spec.setpoint = v.setpoint;
  if (panel.id === "srm-lsm") {
    spec.methods = [{ method: "srm" }, { method: "lsm" }];
    // LSM(2)/(3) of the paper's tables: an estimate over every block of N samples.
    if (v.block > 0) spec.methods.push({ method: "blockls", block: v.block });
  } else if (panel.id === "malsm") {
    spec.methods = [{ method: "malsm", window: v.window }];
  } else if (panel.id === "wlsm") {
    spec.methods = [{ method: "wlsm", gamma: v.gamma, pmax: v.pmax, w0: [v.a0, v.b0] }];
  } else {
    throw new RangeError(`unknown panel ${panel.id}`);
  }
  return spec;
}

/** Which panel a run belongs to, from its methods. */
export function panelOfRun(run) {
  const names = new Set((run?.methods ?? []).map((m) => (typeof m === "string" ? m : (m.method ?? m.name))));
  if (names.has("wlsm")) return "wlsm";
  if (names.has("malsm")) return "malsm";
  return "srm-lsm";
}

/** The method name of an entry of a run's `methods` list. */
export function methodName(m) {
  return typeof m === "string" ? m : String(m.method ?? m.name ?? "");
}

/**
 * A run as the views use it (RunOut of /openapi.json); `estimates` (the
 * latest estimate per method) is filled live by the rig page.
 * @param {any} r
 */
export function readRun(r) {
  if (!r || typeof r !== "object") return null;
  const pick = (camel, snake, d = null) => r[camel] ?? r[snake] ?? d;
  return {
    raw: r,
    id: r.id,
    rig: pick("rig", "rigId"),
    user: pick("username", "user"),
    status: String(r.status ?? "running"),
    dt: Number(r.dt ?? 1),
    nSamples: pick("nSamples", "n_samples"),
    signal: r.signal ?? null,
    setpoint: r.setpoint ?? null,
    methods: Array.isArray(r.methods) ? r.methods : [],
    startedAt: pick("startedAt", "started_at"),
    endedAt: pick("endedAt", "ended_at"),
    endReason: pick("endReason", "end_reason"),
    samples: Number(pick("samplesStored", "samples_stored", 0)),
    results: Array.isArray(r.results) ? r.results : [],
    estimates: new Map(),
  };
}

/** What drove the input: the signal, or the manual set point. */
export function inputText(run) {
  if (run.signal) return run.signal;
  if (run.setpoint !== null && run.setpoint !== undefined) return `set point ${run.setpoint} V (manual)`;
  return "manual";
}
