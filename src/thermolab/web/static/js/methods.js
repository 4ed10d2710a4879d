// @ts-check
// The identification methods, as the server publishes them at GET /api/methods
// (thermolab.ident.registry: name, title, paper's panel, what each returns and
// its settings with their defaults and ranges, plus the ranges the lab narrows
// for a run in `runSettings`). The browser holds no copy of them: loadMethods()
// fetches them once per page load (app.js awaits it before mounting a view) and
// every view reads the methods through this module.

import { api } from "./api.js";

/**
 * @typedef {object} Setting  one setting of a method (GET /api/methods)
 * @property {string} name
 * @property {string} type  "integer", "number", "number_list", "choice", ...
 * @property {unknown} default
 * @property {number | null} [minimum]
 * @property {number | null} [maximum]
 * @property {boolean | null} [exclusiveMinimum]  true: the minimum itself is not allowed
 * @property {boolean | null} [exclusiveMaximum]  true: the maximum itself is not allowed
 * @property {string[] | null} [choices]
 * @property {string | null} [unit]
 * @property {string} [help]
 */
/**
 * @typedef {object} Method  one identification method (GET /api/methods)
 * @property {string} name
 * @property {string} title
 * @property {string} [description]
 * @property {string} panel  the id of the interface's panel that runs it
 * @property {string[]} returns  "final" and/or "trajectory" (an estimate per sample or block)
 * @property {Setting[]} settings
 */

/** The interface's panel ids of the paper's panels 1, 2 and 3 (the registry's `panel`). */
export const PANEL_IDS = Object.freeze(["srm-lsm", "malsm", "wlsm"]);

/** @type {readonly Method[]} */
let current = Object.freeze([]);
/** @type {Promise<void> | null} */
let loading = null;

/**
 * Fetch GET /api/methods once and offer its methods (later calls share the answer).
 * @returns {Promise<void>}
 */
export function loadMethods() {
  loading ??= api.methods().then(useMethods, (err) => {
    loading = null; // try again on the next page
    throw err;
  });
  return loading;
}

/** The methods the interface offers now. */
export function methods() {
  return current;
}

/**
 * A panel id from the registry's panel number (1, 2, 3) or an id already.
 * @param {unknown} panel
 */
function panelId(panel) {
  if (typeof panel === "number") return PANEL_IDS[panel - 1];
  return typeof panel === "string" ? panel : undefined;
}

/**
 * Read the answer of GET /api/methods; throws TypeError on another shape. A setting
 * the lab narrows for a run (`runSettings`) takes the lab's range.
 * @param {any} json
 * @returns {Method[]}
 */
export function readMethods(json) {
  const list = json && typeof json === "object" ? json.methods : null;
  if (!Array.isArray(list)) throw new TypeError("GET /api/methods: no methods list");
  /** @type {Map<string, Setting>} */
  const narrowed = new Map();
  for (const s of Array.isArray(json.runSettings) ? json.runSettings : []) {
    if (s && typeof s.name === "string") narrowed.set(s.name, s);
  }
  return list.map((m) => {
    const panel = m ? panelId(m.panel) : undefined;
    if (!m || typeof m.name !== "string" || panel === undefined) throw new TypeError("GET /api/methods: a method without name or panel");
    const settings = Array.isArray(m.settings) ? m.settings.filter((s) => s && typeof s.name === "string") : [];
    return {
      name: m.name,
      title: String(m.title ?? m.name),
      description: typeof m.description === "string" ? m.description : undefined,
      panel,
      returns: Array.isArray(m.returns) ? m.returns.map(String) : ["final"],
      settings: settings.map((s) => narrowed.get(s.name) ?? s),
    };
  });
}

/**
 * Offer the server's methods from now on (the answer of GET /api/methods).
 * @param {any} json
 */
export function useMethods(json) {
  current = Object.freeze(readMethods(json));
}

/**
 * A method by name (an entry of a run's methods may carry a suffix: "malsm:2").
 * @param {string} name
 */
export function findMethod(name) {
  const base = String(name).split(/[:#]/)[0];
  return current.find((m) => m.name === base);
}

/**
 * Whether a method's estimates form a trajectory (drawn as Ks(k), Ts(k)).
 * @param {string} name
 */
export function hasTrajectory(name) {
  return findMethod(name)?.returns.includes("trajectory") ?? false;
}

/**
 * The names of the methods a panel runs, in the registry's order.
 * @param {string} panel
 */
export function panelMethods(panel) {
  return current.filter((m) => m.panel === panel).map((m) => m.name);
}

/**
 * A setting's allowed range as the form checks it (validate.js's FieldSpec
 * less the label), and its default; an open range and no default while the
 * methods are not loaded (the panels are locked until then).
 * @param {string} method
 * @param {string} setting
 * @returns {{min: number, max: number, exclusiveMin?: boolean, exclusiveMax?: boolean,
 *   integer?: boolean, unit?: string, value: unknown}}
 */
export function settingRange(method, setting) {
  const s = findMethod(method)?.settings.find((x) => x.name === setting);
  if (!s) return { min: -Infinity, max: Infinity, value: undefined };
  return {
    min: s.minimum ?? -Infinity,
    max: s.maximum ?? Infinity,
    ...(s.exclusiveMinimum ? { exclusiveMin: true } : {}),
    ...(s.exclusiveMaximum ? { exclusiveMax: true } : {}),
    ...(s.type === "integer" ? { integer: true } : {}),
    ...(s.unit ? { unit: s.unit } : {}),
    value: s.default,
  };
}
