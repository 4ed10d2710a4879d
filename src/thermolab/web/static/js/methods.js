// @ts-check
// The identification methods, in the shape the server is to publish at
// GET /api/methods (issue 9): name, title, panel, what each returns and its
// settings with their defaults and ranges. Until the server publishes it,
// LOCAL_METHODS is the interface's copy of the library's registry (the one
// table of method facts in the browser code); useMethods() swaps in the
// server's answer, and every view reads the methods through this module.

/**
 * @typedef {object} Setting  one setting of a method (GET /api/methods)
 * @property {string} name
 * @property {string} type  "int", "float" or "float[]"
 * @property {unknown} default
 * @property {number | null} [minimum]
 * @property {number | null} [maximum]
 * @property {number | null} [exclusiveMinimum]
 * @property {number | null} [exclusiveMaximum]
 * @property {string[] | null} [choices]
 * @property {string | null} [unit]
 * @property {string} [help]
 */
/**
 * @typedef {object} Method  one identification method (GET /api/methods)
 * @property {string} name
 * @property {string} title
 * @property {string} [description]
 * @property {string} panel  the paper's panel that runs it
 * @property {string[]} returns  "final" and/or "trajectory" (an estimate per sample or block)
 * @property {Setting[]} settings
 */

/**
 * The interface's copy, until the server publishes its own. Titles are left
 * to the message catalogue (runspec.methodTitle), so each is the method's name.
 * @type {readonly Method[]}
 */
export const LOCAL_METHODS = Object.freeze([
  { name: "srm", title: "srm", panel: "srm-lsm", returns: ["final"], settings: [] },
  { name: "lsm", title: "lsm", panel: "srm-lsm", returns: ["final"], settings: [] },
  {
    name: "blockls",
    title: "blockls",
    panel: "srm-lsm",
    returns: ["final", "trajectory"],
    settings: [{ name: "block", type: "int", default: null, minimum: 2, maximum: 100000, unit: "samples" }],
  },
  {
    name: "malsm",
    title: "malsm",
    panel: "malsm",
    returns: ["final", "trajectory"],
    settings: [{ name: "window", type: "int", default: 100, minimum: 2, maximum: 100000, unit: "samples" }],
  },
  {
    name: "wlsm",
    title: "wlsm",
    panel: "wlsm",
    returns: ["final", "trajectory"],
    settings: [
      { name: "gamma", type: "float", default: 0.96, exclusiveMinimum: 0, exclusiveMaximum: 1 },
      { name: "pmax", type: "float", default: 10000, exclusiveMinimum: 0 },
      { name: "w0", type: "float[]", default: [0.96329, 9.9082e-4] },
    ],
  },
]);

/** @type {readonly Method[]} */
let current = LOCAL_METHODS;

/** The methods the interface offers now. */
export function methods() {
  return current;
}

/**
 * Read the answer of GET /api/methods; throws TypeError on another shape.
 * @param {any} json
 * @returns {Method[]}
 */
export function readMethods(json) {
  const list = json && typeof json === "object" ? json.methods : null;
  if (!Array.isArray(list)) throw new TypeError("GET /api/methods: no methods list");
  return list.map((m) => {
    if (!m || typeof m.name !== "string" || typeof m.panel !== "string") throw new TypeError("GET /api/methods: a method without name or panel");
    return {
      name: m.name,
      title: String(m.title ?? m.name),
      description: typeof m.description === "string" ? m.description : undefined,
      panel: m.panel,
      returns: Array.isArray(m.returns) ? m.returns.map(String) : ["final"],
      settings: Array.isArray(m.settings) ? m.settings.filter((s) => s && typeof s.name === "string") : [],
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
 * less the label), and its default.
 * @param {string} method
 * @param {string} setting
 * @returns {{min: number, max: number, exclusiveMin?: boolean, exclusiveMax?: boolean,
 *   integer?: boolean, unit?: string, value: unknown}}
 */
export function settingRange(method, setting) {
  const s = findMethod(method)?.settings.find((x) => x.name === setting);
  if (!s) throw new RangeError(`no setting ${setting} of ${method}`);
  const lo = s.exclusiveMinimum ?? s.minimum ?? -Infinity;
  const hi = s.exclusiveMaximum ?? s.maximum ?? Infinity;
  return {
    min: lo,
    max: hi,
    ...(s.exclusiveMinimum !== undefined && s.exclusiveMinimum !== null ? { exclusiveMin: true } : {}),
    ...(s.exclusiveMaximum !== undefined && s.exclusiveMaximum !== null ? { exclusiveMax: true } : {}),
    ...(s.type === "int" ? { integer: true } : {}),
    ...(s.unit ? { unit: s.unit } : {}),
    value: s.default,
  };
}
