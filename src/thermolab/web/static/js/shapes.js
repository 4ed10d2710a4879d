// Reading the server's JSON: the one place that knows the field names of
// GET /api/rigs, GET /api/rigs/{rig}, the `access` object of the live protocol
// and GET /api/runs/{run}. Views only see the normalised objects below.

/** Human words for the rig states of the live protocol. */
export const STATE_LABELS = Object.freeze({
  off: "Off",
  starting: "Starting",
  free: "Free",
  in_use: "In use",
  cooldown: "Cooling down",
  fault: "Fault",
  out_of_service: "Out of service",
});

export function stateLabel(state) {
  return STATE_LABELS[state] ?? String(state ?? "unknown");
}

/**
 * The access state as seen by this user (live protocol `access`, also inside
 * GET /api/rigs/{rig}).
 * @returns {{role: string, queueSize: number, queuePosition: number | null,
 *   estimatedTimeUntilControl: number | null, timeLeft: number | null,
 *   controller: string | null, watchers: number, watcherNames: string[] | null,
 *   queue: string[] | null}}
 */
export function readAccess(a) {
  const src = a && typeof a === "object" ? a : {};
  const watchers = src.watchers;
  return {
    role: typeof src.role === "string" ? src.role : "watcher",
    queueSize: numberOr(src.queueSize, 0),
    queuePosition: numberOr(src.queuePosition, null),
    estimatedTimeUntilControl: numberOr(src.estimatedTimeUntilControl, null),
    timeLeft: numberOr(src.timeLeft, null),
    controller: typeof src.controller === "string" ? src.controller : (src.controller?.username ?? null),
    watchers: Array.isArray(watchers) ? watchers.length : numberOr(watchers, 0),
    watcherNames: Array.isArray(watchers) ? watchers.map(nameOf) : (Array.isArray(src.watcherNames) ? src.watcherNames : null),
    queue: Array.isArray(src.queue) ? src.queue.map(nameOf) : null,
  };
}

function nameOf(x) {
  return typeof x === "string" ? x : (x?.username ?? String(x));
}

function numberOr(v, fallback) {
  return typeof v === "number" && Number.isFinite(v) ? v : fallback;
}

/**
 * A rig as the interface needs it (GET /api/rigs items, GET /api/rigs/{rig},
 * the `rig` of a hello message).
 */
export function readRig(r) {
  const src = r && typeof r === "object" ? r : {};
  const info = src.info && typeof src.info === "object" ? src.info : src;
  const range = src.input_range ?? info.input_range ?? [info.input_min ?? -10, info.input_max ?? 10];
  return {
    id: String(src.id ?? src.name ?? ""),
    title: String(src.title ?? src.id ?? src.name ?? ""),
    state: String(src.state ?? "off"),
    detail: typeof src.detail === "string" ? src.detail : (src.fault ?? null),
    inputMin: Number(range[0]),
    inputMax: Number(range[1]),
    inputUnit: String(info.input_unit ?? "V"),
    outputUnit: String(info.output_unit ?? "V"),
    safeInput: numberOr(info.safe_input, 0),
    limits: src.limits && typeof src.limits === "object" ? src.limits : {},
    access: readAccess(src.access),
    raw: src,
  };
}
