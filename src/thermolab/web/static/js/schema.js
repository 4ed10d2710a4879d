// @ts-check
// The ranges the server accepts, read from its own OpenAPI document
// (/openapi.json), so the panels show and check exactly what the server will
// take, and stay right when the server's limits change.

let cached = null;

/** The OpenAPI document, fetched once per page load (null if unavailable). */
export function openapi() {
  if (!cached) {
    cached = fetch("/openapi.json", { credentials: "same-origin" })
      .then((res) => (res.ok ? res.json() : null))
      .catch(() => null);
  }
  return cached;
}

/**
 * Numeric constraints of one property of a schema: {min, max, exclusiveMin,
 * exclusiveMax, integer}, from `minimum`/`exclusiveMinimum`... of the
 * property or of the non-null branch of its `anyOf`. Null when absent.
 * @param {any} doc the OpenAPI document
 * @param {string} schemaName e.g. "RunIn"
 * @param {string} prop e.g. "dt"
 */
export function numericRange(doc, schemaName, prop) {
  const schema = doc?.components?.schemas?.[schemaName]?.properties?.[prop];
  if (!schema) return null;
  const branch = Array.isArray(schema.anyOf) ? schema.anyOf.find((s) => s.type === "number" || s.type === "integer") : schema;
  if (!branch) return null;
  const out = { integer: branch.type === "integer" };
  if (typeof branch.minimum === "number") out.min = branch.minimum;
  if (typeof branch.exclusiveMinimum === "number") {
    out.min = branch.exclusiveMinimum;
    out.exclusiveMin = true;
  }
  if (typeof branch.maximum === "number") out.max = branch.maximum;
  if (typeof branch.exclusiveMaximum === "number") {
    out.max = branch.exclusiveMaximum;
    out.exclusiveMax = true;
  }
  return out;
}

/** Whether a schema has a property (an optional capability of the server). */
export function hasProperty(doc, schemaName, prop) {
  return Boolean(doc?.components?.schemas?.[schemaName]?.properties?.[prop]);
}

/**
 * The string choices a property accepts: the `enum` of the property or of a
 * branch of its `anyOf` (e.g. RunIn.offset: "auto", "initial"...). Null when none.
 * @param {any} doc the OpenAPI document
 * @param {string} schemaName
 * @param {string} prop
 */
export function enumValues(doc, schemaName, prop) {
  const schema = doc?.components?.schemas?.[schemaName]?.properties?.[prop];
  if (!schema) return null;
  const branches = Array.isArray(schema.anyOf) ? schema.anyOf : [schema];
  const found = branches.find((s) => Array.isArray(s.enum));
  return found ? found.enum.filter((v) => typeof v === "string") : null;
}
