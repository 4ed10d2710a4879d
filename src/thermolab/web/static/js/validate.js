// Client-side checks of numeric fields, before anything is sent. The server
// checks again (it is the authority); these only spare a round trip and say
// exactly what is allowed next to the field.

/**
 * @typedef {object} FieldSpec
 * @property {string} label   what the field is, for messages
 * @property {number} min
 * @property {number} max
 * @property {boolean} [integer]
 * @property {boolean} [exclusiveMin]  min itself not allowed (γ > 0 ...)
 * @property {boolean} [exclusiveMax]
 * @property {string} [unit]
 */

/** Text of the allowed range, e.g. "−10 to 10 V" or "an integer from 10 to 100000". */
export function rangeText(spec) {
  const unit = spec.unit ? ` ${spec.unit}` : "";
  const integer = spec.integer ? "an integer " : "";
  const lo = `${spec.exclusiveMin ? "more than" : "at least"} ${num(spec.min)}`;
  if (spec.max === undefined || spec.max === Infinity) return `${integer}${lo}${unit}`;
  if (!spec.exclusiveMin && !spec.exclusiveMax) {
    return `${spec.integer ? "an integer from " : ""}${num(spec.min)} to ${num(spec.max)}${unit}`;
  }
  const hi = `${spec.exclusiveMax ? "less than" : "at most"} ${num(spec.max)}`;
  return `${integer}${lo} and ${hi}${unit}`;
}

function num(v) {
  // A true minus sign reads better and screen readers say "minus".
  return String(v).replace(/^-/, "−");
}

/**
 * Parse and check one field's text.
 * @param {string} text
 * @param {FieldSpec} spec
 * @returns {{ok: true, value: number} | {ok: false, error: string}}
 */
export function checkNumber(text, spec) {
  const t = String(text).trim().replace(/^−/, "-").replace(",", ".");
  if (t === "") return { ok: false, error: `${spec.label} is required (${rangeText(spec)}).` };
  // Number("") is 0 and Number("0x10") is 16: accept plain decimal notation only.
  if (!/^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$/.test(t)) {
    return { ok: false, error: `${spec.label} must be a number (${rangeText(spec)}).` };
  }
  const v = Number(t);
  if (!Number.isFinite(v)) {
    return { ok: false, error: `${spec.label} must be a finite number (${rangeText(spec)}).` };
  }
  if (spec.integer && !Number.isInteger(v)) {
    return { ok: false, error: `${spec.label} must be a whole number (${rangeText(spec)}).` };
  }
  const belowMin = spec.exclusiveMin ? v <= spec.min : v < spec.min;
  const max = spec.max ?? Infinity;
  const aboveMax = spec.exclusiveMax ? v >= max : v > max;
  if (belowMin || aboveMax) {
    return { ok: false, error: `${spec.label} must be ${rangeText(spec)}; got ${num(v)}.` };
  }
  return { ok: true, value: v };
}

/**
 * Check several fields at once.
 * @param {Record<string, string>} texts
 * @param {Record<string, FieldSpec>} specs
 * @returns {{values: Record<string, number>, errors: Record<string, string>}}
 */
export function checkAll(texts, specs) {
  const values = {};
  const errors = {};
  for (const [name, spec] of Object.entries(specs)) {
    const r = checkNumber(texts[name] ?? "", spec);
    if (r.ok) values[name] = r.value;
    else errors[name] = r.error;
  }
  return { values, errors };
}
