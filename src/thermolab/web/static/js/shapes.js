// @ts-check
// Reading the server's JSON: the one place that knows the field names of
// GET /api/rigs, GET /api/rigs/{rig}, the `access` object of the live protocol
// and GET /api/runs/{run}. Views only see the normalised objects below.

import { t } from "./i18n.js";
import { messages as english } from "./messages/en.js";

/** The message of each rig state of the live protocol. */
export const STATE_LABELS = Object.freeze({
  off: "rigState.off",
  starting: "rigState.starting",
  free: "rigState.free",
  in_use: "rigState.in_use",
  cooldown: "rigState.cooldown",
  fault: "rigState.fault",
  out_of_service: "rigState.out_of_service",
});

export function stateLabel(state) {
  const key = STATE_LABELS[state];
  return key ? t(key) : String(state ?? t("rigState.unknown"));
}

/**
 * The access state as seen by this user: `access` of GET /api/rigs/{rig}
 * (AccessOut in /openapi.json) and of the live protocol's `access` message.
 * @returns {{role: "controller" | "queued" | "watcher", queueSize: number,
 *   queuePosition: number | null, estimatedTimeUntilControl: number | null,
 *   timeLeft: number | null, idleTimeLeft: number | null, controller: string | null,
 *   controllerName: string | null, watchers: number, canExtend: boolean}}
 */
export function readAccess(a) {
  const src = a && typeof a === "object" ? a : {};
  return {
    role: src.role === "controller" || src.role === "queued" ? src.role : "watcher",
    queueSize: numberOr(src.queueSize, 0),
    queuePosition: numberOr(src.queuePosition, null),
    estimatedTimeUntilControl: numberOr(src.estimatedTimeUntilControl, null),
    timeLeft: numberOr(src.timeLeft, null),
    idleTimeLeft: numberOr(src.idleTimeLeft, null),
    controller: typeof src.controller === "string" ? src.controller : null,
    /** The controller's display name, when they gave one. */
    controllerName: typeof src.controllerName === "string" ? src.controllerName : null,
    watchers: numberOr(src.watchers, 0),
    canExtend: src.canExtend === true,
  };
}

/**
 * How a person is named on a page: the display name, else the login name; with
 * `withLogin` (a teacher's lists, where the login name is what actions take) both.
 * @param {string} username
 * @param {string | null | undefined} displayName
 * @param {boolean} [withLogin]
 */
export function personName(username, displayName, withLogin = false) {
  if (!displayName) return username;
  return withLogin ? t("person.withLogin", { name: displayName, user: username }) : displayName;
}

function numberOr(v, fallback) {
  return typeof v === "number" && Number.isFinite(v) ? v : fallback;
}

/**
 * An actuator of a rig besides its input (ActuatorOut in /openapi.json): `recorded`
 * when every run records it (a kit's heater 2), not only a closed loop (a twin's fan).
 * @returns {{name: string, unit: string, min: number, max: number, default: number, level: number | null, recorded: boolean}}
 */
function readActuator(a) {
  const src = a && typeof a === "object" ? a : {};
  return {
    name: String(src.name ?? ""),
    unit: String(src.unit ?? ""),
    min: numberOr(src.min, 0),
    max: numberOr(src.max, 100),
    default: numberOr(src.default, 0),
    level: numberOr(src.level, null),
    recorded: src.recorded === true,
  };
}

/**
 * An output of a rig besides y (FurtherOutputOut in /openapi.json: a kit's sensor 2).
 * @returns {{name: string, unit: string}}
 */
function readFurtherOutput(o) {
  const src = o && typeof o === "object" ? o : {};
  return { name: String(src.name ?? ""), unit: String(src.unit ?? "") };
}

/**
 * A rig (RigOut in /openapi.json: GET /api/rigs items, GET /api/rigs/{rig},
 * the answers of the control routes, the `rig` of a hello message).
 */
export function readRig(r) {
  const src = r && typeof r === "object" ? r : {};
  const input = src.input && typeof src.input === "object" ? src.input : {};
  return {
    id: String(src.id ?? ""),
    title: String(src.title ?? src.id ?? ""),
    kind: String(src.kind ?? ""),
    state: String(src.state ?? "off"),
    inService: src.inService !== false,
    detail: typeof src.fault === "string" ? src.fault : null,
    inputMin: numberOr(input.min, -10),
    inputMax: numberOr(input.max, 10),
    inputUnit: String(input.unit ?? "V"),
    safeInput: numberOr(input.safe, 0),
    lastInput: numberOr(input.last, null),
    live: input.live !== false,
    // Every actuator besides the input (a twin's fan): its level now and its declared
    // default, where each turn and run starts (issue #23).
    actuators: Array.isArray(src.actuators) ? src.actuators.map(readActuator) : [],
    // Every output besides y (a kit's sensor 2, t2): each reading carries it.
    outputs: Array.isArray(src.outputs) ? src.outputs.map(readFurtherOutput) : [],
    outputUnit: String(src.outputUnit ?? "V"),
    // Times real time: 1 for hardware, a twin's pace, null for a rig host's twin not yet heard.
    speedup: numberOr(src.speedup, null),
    limits: src.limits && typeof src.limits === "object" ? src.limits : {},
    access: readAccess(src.access),
    // Teachers only (null for students).
    queue: Array.isArray(src.queue) ? src.queue : null,
    watcherList: Array.isArray(src.watcherList) ? src.watcherList : null,
  };
}

/**
 * A rig's title for a page. The title the lab ships its default rig with
 * (thermolab.lab.config.model DEFAULT_RIG) is the English catalogue's
 * rig.defaultTitle (tests/web/test_messages.py keeps the two equal): the lab's
 * own words, so shown in the reader's language. A title an operator wrote is
 * shown as written.
 * @param {{id: string, title?: string | null}} rig
 */
export function rigTitle(rig) {
  if (rig.title === english["rig.defaultTitle"]) return t("rig.defaultTitle");
  return rig.title || rig.id;
}
