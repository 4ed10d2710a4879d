// @ts-check
// Runs: the body of POST /api/rigs/{rig}/runs built from a panel, and the run
// objects of GET /api/runs/{run} read into one shape for the views.

import { t } from "./i18n.js";
import { findMethod } from "./methods.js";

/** The translated titles of the methods (others show the title the server gives). */
const METHOD_TITLES = {
  srm: "method.srm",
  lsm: "method.lsm",
  blockls: "method.blockls",
  malsm: "method.malsm",
  wlsm: "method.wlsm",
  oe: "method.oe",
};

export function methodTitle(method) {
  if (method === "srm-lsm") return t("method.srmLsm");
  const key = METHOD_TITLES[method];
  return key ? t(key) : (findMethod(method)?.title ?? String(method));
}

/** The translated words for a run's status (others show the server's word). */
const RUN_STATUS_TEXT = {
  running: "runStatus.running",
  finished: "runStatus.finished",
  stopped: "runStatus.stopped",
  interrupted: "runStatus.interrupted",
  failed: "runStatus.failed",
  aborted: "runStatus.aborted",
};

/**
 * A run's status (RunOut.status) in the reader's language.
 * @param {string} status
 */
export function runStatusText(status) {
  const key = RUN_STATUS_TEXT[status];
  return key ? t(key) : String(status);
}

/** The square wave of the Automatic option: ten times slower than sampling. */
export function automaticSignal(low, high, dt) {
  const freq = 1 / (10 * dt);
  return `square:${low}:${high}:${Number(freq.toPrecision(12))}`;
}

/** A planned step of the set point: from `from` to `to` at `at` seconds after START. */
export function plannedStepSignal(from, to, at) {
  return `step:${from}:${to}@${at}`;
}

/** Whether a run's input is a panel's planned step (a step signal) rather than the Automatic wave. */
export function isPlannedStep(run) {
  return typeof run?.signal === "string" && run.signal.startsWith("step:");
}

/**
 * The body of POST /api/rigs/{rig}/runs (RunIn of /openapi.json) for a panel's
 * checked values.
 * @param {{id: string}} panel
 * @param {Record<string, any>} v  checked values (dt, n, setpoint [stepTo, stepAt] | low/high,
 *   block, window, gamma, pmax, a0, b0; offset: the operating-point mode; pair: "input>output")
 * @param {boolean} automatic
 * @param {{w0?: boolean, offset?: boolean}} [server]  what the server accepts beyond the basics
 */
export function buildRunSpec(panel, v, automatic, server = {}) {
  const spec = { dt: v.dt, samples: v.n };
  if (automatic) spec.signal = automaticSignal(v.low, v.high, v.dt);
  // Checked values hold stepTo/stepAt only when the panel's planned step is on.
  else if (v.stepTo !== undefined && v.stepAt !== undefined) spec.signal = plannedStepSignal(v.setpoint, v.stepTo, v.stepAt);
  else spec.setpoint = v.setpoint;
  if (panel.id === "srm-lsm") {
    spec.methods = ["srm", "lsm"];
    // LSM(2)/(3) of the paper's tables: an estimate over every block of N samples.
    if (v.block > 0) {
      spec.methods.push("blockls");
      spec.block = v.block;
    }
  } else if (panel.id === "malsm") {
    spec.methods = ["malsm"];
    spec.window = v.window;
  } else if (panel.id === "wlsm") {
    spec.methods = ["wlsm"];
    spec.gamma = v.gamma;
    spec.pmax = v.pmax;
    if (server.w0 && v.a0 !== undefined) spec.w0 = [v.a0, v.b0];
  } else {
    throw new RangeError(`unknown panel ${panel.id}`);
  }
  if (server.offset && typeof v.offset === "string" && v.offset) spec.offset = v.offset;
  // The pair chosen ("q2>t2"); the standard pair is the request's default, not sent.
  if (typeof v.pair === "string" && v.pair && v.pair !== "u>y") {
    const [input, output] = v.pair.split(">");
    spec.input = input;
    spec.output = output;
  }
  return spec;
}

/**
 * The input/output pair a run identified (RunIn.input, RunIn.output: a kit's "q2", "t2"),
 * by its record's column names; "u", "y" for a run that named none.
 * @param {{settings?: Record<string, any>} | null | undefined} run
 * @returns {{input: string, output: string}}
 */
export function runPair(run) {
  const s = run?.settings ?? {};
  return { input: typeof s.input === "string" ? s.input : "u", output: typeof s.output === "string" ? s.output : "y" };
}

/** The panel of the step and least-squares methods, which a run belongs to by default. */
const FIRST_PANEL = "srm-lsm";

/** Which panel a run belongs to, from its methods (methods.js says each one's panel). */
export function panelOfRun(run) {
  for (const m of run?.methods ?? []) {
    const panel = findMethod(methodName(m))?.panel;
    if (panel && panel !== FIRST_PANEL) return panel;
  }
  return FIRST_PANEL;
}

/** The method name of an entry of a run's `methods` list. */
export function methodName(m) {
  return typeof m === "string" ? m : String(m.method ?? m.name ?? "");
}

/**
 * A run as the views use it (RunOut of /openapi.json). `estimates` holds the
 * latest estimate per method: from the run's `results` at first, then from
 * the live `estimate` messages.
 * @param {any} r
 */
export function readRun(r) {
  if (!r || typeof r !== "object") return null;
  const estimates = new Map();
  const results = r.results && typeof r.results === "object" ? r.results : {};
  for (const [method, res] of Object.entries(results)) {
    const latest = res?.latest;
    if (latest && typeof latest === "object") estimates.set(method, withConvergence(readEstimate(latest), res));
  }
  return {
    raw: r,
    id: r.id,
    rig: r.rig ?? null,
    user: r.username ?? null,
    /** The owner's display name, when they gave one. */
    userName: typeof r.displayName === "string" ? r.displayName : null,
    status: String(r.status ?? "running"),
    dt: Number(r.dt ?? 1),
    nSamples: r.samples ?? null,
    signal: r.signal ?? null,
    setpoint: r.setpoint ?? null,
    methods: Array.isArray(r.methods) ? r.methods.map(methodName) : [],
    settings: r.settings ?? {},
    startedAt: r.startedAt ?? null,
    // The planned end (START plus samples × dt in real time; null for older runs).
    endsAt: r.endsAt ?? null,
    // How well the run kept its sampling times (once it is over; null before).
    timing: r.timing && typeof r.timing === "object" ? r.timing : null,
    endedAt: r.endedAt ?? null,
    endReason: r.endReason ?? null,
    samples: Number(r.samplesTaken ?? r.samplesStored ?? 0),
    results,
    estimates,
    // How the identifiers treated the operating point, and why (null for older runs).
    operatingPoint: r.operatingPoint && typeof r.operatingPoint === "object" ? r.operatingPoint : null,
  };
}

/** An estimate (live `estimate` message, or a result's `latest`) for display. */
export function readEstimate(e) {
  const num = (v) => (typeof v === "number" && Number.isFinite(v) ? v : Number.NaN);
  return {
    K: num(e.K),
    tau: num(e.tau),
    k: e.k,
    // The dead time θ (s) of the first order plus dead time model (0 for eq. 4's ARX).
    theta: num(e.extras?.theta ?? e.theta),
    // SRM: the gain read from the last sample, the figure the paper's Table I prints.
    Klast: num(e.extras?.K_last_sample),
    valid: e.valid !== false && Number.isFinite(num(e.K)),
    final: Boolean(e.final),
    W: e.W,
    reason: e.reason ?? e.extras?.reason ?? null,
    // The library's warnings on this estimate (each says what it means and what to do);
    // an estimate with any, or marked untrusted, never shows as final.
    warnings: estimateWarnings(e),
    // How this method handled the operating point and what it found (offset "auto":
    // decided from the record by the library), or null.
    operatingPoint: e.extras?.operating_point && typeof e.extras.operating_point === "object" ? e.extras.operating_point : null,
    trusted: e.extras?.trusted ?? e.trusted ?? estimateWarnings(e).length === 0,
  };
}

/**
 * Whether a result's estimates converged, as the server judged them at END
 * (`stats.converged`: the paper's count, over the samples after convergence):
 * false only when the server says so; true for methods with a single
 * estimate and for runs stored before the server judged it.
 * @param {any} res  a run's result ({latest, stats, ...})
 */
export function converged(res) {
  return res?.stats?.converged !== false;
}

/**
 * An estimate whose run never converged is one point of a scatter (the
 * paper's Table II), never a final model: it is marked untrusted and says so.
 * @param {ReturnType<typeof readEstimate>} est
 * @param {any} res
 */
function withConvergence(est, res) {
  if (converged(res)) return { ...est, notConverged: false };
  return { ...est, notConverged: true, trusted: false };
}

/** The warnings an estimate carries (its extras', from the online identifiers). */
function estimateWarnings(e) {
  const list = e.extras?.warnings ?? e.warnings;
  return Array.isArray(list) ? list.map(String) : [];
}

/** What drove the input, in words (runwords.js); kept here for the views that import it from runs. */
export { inputText } from "./runwords.js";
