// @ts-check
// The HTTP API (issue 4, /openapi.json): one place that knows how requests are
// made and how the server's errors look, so every view shows the server's
// message: the catalogue's translation of its stable `code` when there is one,
// else, on a page not in English, the server's sentence for the code in the
// page's language (`message`; every request names that language in
// Accept-Language), else its own English text (`detail`) as it comes.

import { formatDateTime, language, serverMessage, t } from "./i18n.js";

/** An HTTP answer that was not 2xx, carrying the server's message. */
export class ApiError extends Error {
  /**
   * @param {number} status
   * @param {string} message
   * @param {unknown} body
   */
  constructor(status, message, body) {
    super(message);
    this.name = "ApiError";
    this.status = status;
    this.body = body;
  }
}

/**
 * The human-readable message of an error body: FastAPI answers either
 * `{"detail": "text"}` or, for a request that fails validation,
 * `{"detail": [{"loc": [...], "msg": "..."}]}`.
 * @param {unknown} body
 * @param {string} fallback
 */
export function errorMessage(body, fallback) {
  if (body && typeof body === "object" && "detail" in body) {
    const detail = /** @type {any} */ (body).detail;
    // A stable code beside the text ({"detail": "...", "code": "..."}) or with
    // it ({"detail": {"code": "...", "message": "...", "params": {...}}}).
    const coded = detail && typeof detail === "object" && !Array.isArray(detail) ? detail : body;
    const own = /** @type {any} */ (body).message;
    const translated = typeof detail === "string" && typeof own === "string" && own && language() !== "en";
    const text = translated ? own : typeof detail === "string" ? detail : typeof coded.message === "string" ? coded.message : "";
    if (typeof coded.code === "string") return serverMessage(coded.code, text || fallback, coded.params ?? slotParams(body));
    if (typeof detail === "string" && detail) return detail;
    if (Array.isArray(detail) && detail.length) {
      return detail
        .map((d) => {
          if (!d || typeof d !== "object") return String(d);
          const loc = Array.isArray(d.loc) ? d.loc.filter((p) => p !== "body").join(".") : "";
          return loc ? `${loc}: ${d.msg}` : String(d.msg);
        })
        .join("; ");
    }
  }
  if (typeof body === "string" && body.trim()) return body.trim();
  return fallback;
}

/**
 * The slot a booking refusal names (409 booking_clash, rig_booked: its `slot`),
 * as message parameters in the reader's time zone and language.
 * @param {unknown} body
 * @returns {Record<string, string>}
 */
function slotParams(body) {
  const slot = body && typeof body === "object" ? /** @type {any} */ (body).slot : null;
  if (!slot || typeof slot !== "object") return {};
  /** @param {unknown} iso */
  const at = (iso) => (typeof iso === "string" ? formatDateTime(new Date(iso), { dateStyle: "medium", timeStyle: "short" }) : "");
  const rigs = Array.isArray(slot.rigs) ? slot.rigs.join(", ") : "";
  return { start: at(slot.startsAt), end: at(slot.endsAt), course: String(slot.course ?? ""), rigs };
}

/**
 * The spreadsheet form of a CSV download: the page's language and the browser's
 * time zone (?dialect=pt-BR&tz=America/Sao_Paulo), so that Excel or LibreOffice
 * opens it as columns, with accents, the language's decimal mark and local times.
 * Without them a route answers the plain machine form.
 * @param {string} url  a CSV route, with or without a query
 * @returns {string}
 */
export function spreadsheetUrl(url) {
  // No zone known: the server writes UTC and names it in the headings.
  const zone = Intl.DateTimeFormat().resolvedOptions().timeZone;
  const tz = zone ? `&tz=${encodeURIComponent(zone)}` : "";
  return `${url}${url.includes("?") ? "&" : "?"}dialect=${encodeURIComponent(language())}${tz}`;
}

/** Called on any 401, so that the app can go back to the login page. */
let onUnauthorized = () => {};

export function setUnauthorizedHandler(fn) {
  onUnauthorized = fn;
}

/**
 * Make a request to the API and return its decoded JSON (or null for 204).
 * @param {string} method
 * @param {string} path starting with /api/
 * @param {unknown} [body] sent as JSON
 * @param {{signal?: AbortSignal, quiet401?: boolean, raw?: ArrayBuffer, rawType?: string, form?: FormData}} [opts]
 *   raw: bytes sent as they are (a file), with Content-Type rawType;
 *   form: a multipart form (files), its Content-Type (with the boundary) set by the browser
 */
export async function request(method, path, body, opts = {}) {
  /** @type {RequestInit} */
  const init = {
    method,
    credentials: "same-origin",
    headers: { Accept: "application/json", "Accept-Language": language() },
    signal: opts.signal,
  };
  if (body !== undefined) {
    init.headers = { Accept: "application/json", "Accept-Language": language(), "Content-Type": "application/json" };
    init.body = JSON.stringify(body);
  } else if (opts.raw !== undefined) {
    init.headers = { Accept: "application/json", "Accept-Language": language(), "Content-Type": opts.rawType ?? "application/octet-stream" };
    init.body = opts.raw;
  } else if (opts.form !== undefined) {
    init.body = opts.form;
  }
  let res;
  try {
    res = await fetch(path, init);
  } catch (err) {
    if (err && err.name === "AbortError") throw err;
    throw new ApiError(0, t("api.unreachable"), null);
  }
  const type = res.headers.get("Content-Type") || "";
  let data = null;
  if (res.status !== 204) {
    data = type.includes("json") ? await res.json().catch(() => null) : await res.text();
  }
  if (!res.ok) {
    if (res.status === 401 && !opts.quiet401) onUnauthorized();
    throw new ApiError(res.status, errorMessage(data, `${res.status} ${res.statusText}`), data);
  }
  return data;
}

const enc = encodeURIComponent;

/** The endpoints the interface uses, by name. */
export const api = {
  session: () => request("GET", "/api/session", undefined, { quiet401: true }),
  login: (username, password) => request("POST", "/api/session", { username, password }, { quiet401: true }),
  logout: () => request("DELETE", "/api/session", undefined, { quiet401: true }),
  rigs: (opts) => request("GET", "/api/rigs", undefined, opts),
  agents: (opts) => request("GET", "/api/agents", undefined, opts),
  audit: (opts) => request("GET", "/api/audit", undefined, opts),
  rig: (rig, opts) => request("GET", `/api/rigs/${enc(rig)}`, undefined, opts),
  askControl: (rig) => request("POST", `/api/rigs/${enc(rig)}/control`),
  releaseControl: (rig) => request("DELETE", `/api/rigs/${enc(rig)}/control`),
  setInput: (rig, u) => request("PUT", `/api/rigs/${enc(rig)}/input`, { u }),
  setChannel: (rig, name, level) => request("PUT", `/api/rigs/${enc(rig)}/channels/${enc(name)}`, { level }),
  startRun: (rig, spec) => request("POST", `/api/rigs/${enc(rig)}/runs`, spec),
  stopRun: (rig) => request("POST", `/api/rigs/${enc(rig)}/runs/current/stop`),
  extendControl: (rig, seconds) => request("POST", `/api/rigs/${enc(rig)}/control/extend`, { seconds }),
  moreTime: (rig) => request("POST", `/api/rigs/${enc(rig)}/control/more-time`),
  kick: (rig, username) =>
    request("POST", `/api/rigs/${enc(rig)}/control/kick`, username ? { username } : {}),
  controlSessions: (rig, opts) => request("GET", `/api/rigs/${enc(rig)}/control-sessions`, undefined, opts),
  setService: (rig, inService) => request("PUT", `/api/rigs/${enc(rig)}/service`, { inService }),
  methods: (opts) => request("GET", "/api/methods", undefined, opts),
  runs: (query = "", opts) => request("GET", `/api/runs${query}`, undefined, opts),
  run: (id, opts) => request("GET", `/api/runs/${enc(id)}`, undefined, opts),
  csvUrl: (id) => `/api/runs/${enc(id)}/samples.csv`,
  exportUrl: (id) => `/api/runs/${enc(id)}/export.json`,
  myDataUrl: () => "/api/me/export",
  /** The lab's retention period (no login): {retentionMonths: number | null, retentionAction: "pseudonymise" | "delete"}. */
  privacy: (opts) => request("GET", "/api/privacy", undefined, opts),
  /** Everything stored about a run: {run, channels: [{name, unit, role, description}], samples: {channel name: values}, methods: {label: {method, params, result}}}. */
  exportRun: (id, opts) => request("GET", `/api/runs/${enc(id)}/export.json`, undefined, opts),
  cameraUrl: (rig) => `/api/rigs/${enc(rig)}/camera`,
  tokens: (opts) => request("GET", "/api/tokens", undefined, opts),
  /** A new API token: the answer's `token` is the secret, shown this once. */
  createToken: (spec) => request("POST", "/api/tokens", spec),
  revokeToken: (id) => request("DELETE", `/api/tokens/${enc(id)}`),
  changePassword: (user, currentPassword, password) =>
    request("PUT", `/api/users/${enc(user)}/password`, { password, currentPassword }),
  courses: (opts) => request("GET", "/api/courses", undefined, opts),
  course: (name, opts) => request("GET", `/api/courses/${enc(name)}`, undefined, opts),
  createCourse: (spec) => request("POST", "/api/courses", spec),
  /** A class list (the CSV file's bytes, as they are): {created: {user: one-time password}, updated, unchanged}. */
  uploadRoster: (name, bytes) =>
    request("PUT", `/api/courses/${enc(name)}/roster`, undefined, { raw: bytes, rawType: "text/csv" }),
  rotateCode: (name) => request("POST", `/api/courses/${enc(name)}/enrol-code`),
  resetPassword: (user, currentPassword) =>
    request("POST", `/api/users/${enc(user)}/password-reset`, { currentPassword }),
  enrol: (spec) => request("POST", "/api/enrol", spec, { quiet401: true }),
  setCourseRigs: (name, rigs) => request("PUT", `/api/courses/${enc(name)}/rigs`, { rigs }),
  /** Make an account a teaching assistant of a course; the course (its roster) back. */
  addAssistant: (name, user) => request("PUT", `/api/courses/${enc(name)}/assistants/${enc(user)}`),
  /** Close a course for the term (read-only from then on). */
  closeCourse: (name) => request("POST", `/api/courses/${enc(name)}/close`),
  /** The next term's course: spec {name, title?, starts: "YYYY-MM-DD"} or {name, shiftDays}. */
  copyCourse: (name, spec) => request("POST", `/api/courses/${enc(name)}/copy`, spec),
  /** A course's limits during its slots: {version, rule, updatedBy, settings: [{name, minimum, maximum, nullable, overridden, value}]}. */
  courseSettings: (name, opts) => request("GET", `/api/courses/${enc(name)}/settings`, undefined, opts),
  saveCourseSettings: (name, change) => request("PUT", `/api/courses/${enc(name)}/settings`, change),
  /** A rig's teacher settings: {version, inputUnit, outputUnit, settings: [{name, type, unit, minimum, maximum, choices, nullable, applies, value}]}. */
  rigSettings: (rig, opts) => request("GET", `/api/rigs/${enc(rig)}/settings`, undefined, opts),
  saveRigSettings: (rig, change) => request("PUT", `/api/rigs/${enc(rig)}/settings`, change),
  assignments: (opts) => request("GET", "/api/assignments", undefined, opts),
  assignment: (id, opts) => request("GET", `/api/assignments/${enc(id)}`, undefined, opts),
  createAssignment: (course, spec) => request("POST", `/api/courses/${enc(course)}/assignments`, spec),
  updateAssignment: (id, spec) => request("PUT", `/api/assignments/${enc(id)}`, spec),
  publishAssignment: (id) => request("POST", `/api/assignments/${enc(id)}/publish`),
  /** A hand-in: {runId, K, tau, theta, conclusion}; the answer carries the mark and the feedback. */
  handIn: (id, spec) => request("POST", `/api/assignments/${enc(id)}/submissions`, spec),
  submissions: (id, opts) => request("GET", `/api/assignments/${enc(id)}/submissions`, undefined, opts),
  gradesUrl: (course) => `/api/courses/${enc(course)}/grades.csv`,
  /** Each student's standing: {student, displayName, state, mark, automaticMark, max, comment, overridden, late, deadline, extended, group}. */
  standings: (id, opts) => request("GET", `/api/assignments/${enc(id)}/standings`, undefined, opts),
  /** A teacher's mark for a student: {mark, comment}. */
  overrideMark: (id, student, spec) => request("PUT", `/api/assignments/${enc(id)}/overrides/${enc(student)}`, spec),
  removeOverride: (id, student) => request("DELETE", `/api/assignments/${enc(id)}/overrides/${enc(student)}`),
  /** One student's later deadline: {deadline}. */
  extendDeadline: (id, student, spec) => request("PUT", `/api/assignments/${enc(id)}/extensions/${enc(student)}`, spec),
  removeExtension: (id, student) => request("DELETE", `/api/assignments/${enc(id)}/extensions/${enc(student)}`),
  /** A course's lab groups: [{id, name, members: [{username, displayName}]}]. */
  groups: (course, opts) => request("GET", `/api/courses/${enc(course)}/groups`, undefined, opts),
  createGroup: (course, spec) => request("POST", `/api/courses/${enc(course)}/groups`, spec),
  removeGroup: (course, id) => request("DELETE", `/api/courses/${enc(course)}/groups/${enc(id)}`),
  /** Bookings overlapping [from, to) (ISO instants), as the reader may see them. */
  bookings: (from, to, opts) =>
    request("GET", `/api/bookings?from=${enc(from)}&to=${enc(to)}`, undefined, opts),
  book: (spec) => request("POST", "/api/bookings", spec),
  editBooking: (id, spec) => request("PUT", `/api/bookings/${enc(id)}`, spec),
  cancelBooking: (id) => request("DELETE", `/api/bookings/${enc(id)}`),
  /** The same slot every week until a day, at its wall-clock time in `zone` (IANA; left out:
   * the lab's): {course, rigs, startsAt, endsAt, until, skipClashes, zone}. */
  bookSeries: (spec) => request("POST", "/api/booking-series", spec),
  bookingQuota: (course, opts) => request("GET", `/api/courses/${enc(course)}/booking-quota`, undefined, opts),
  setBookingQuota: (course, minutesPerWeek) =>
    request("PUT", `/api/courses/${enc(course)}/booking-quota`, { minutesPerWeek }),
  /** The reader's courses that let students book for themselves, with this week's use. */
  ownBookingCourses: (opts) => request("GET", "/api/own-bookings", undefined, opts),
  bookOwn: (course, spec) => request("POST", `/api/courses/${enc(course)}/own-bookings`, spec),
  calendarFeeds: (opts) => request("GET", "/api/calendar-feeds", undefined, opts),
  /** A new secret iCalendar address (its url is in this answer only); course: null for all. */
  createCalendarFeed: (course) => request("POST", "/api/calendar-feeds", { course }),
  revokeCalendarFeed: (id) => request("DELETE", `/api/calendar-feeds/${enc(id)}`),
  reminders: (opts) => request("GET", "/api/reminders", undefined, opts),
  setReminders: (email, minutesBefore) => request("PUT", "/api/reminders", { email, minutesBefore }),
  stopReminders: () => request("DELETE", "/api/reminders"),
  /** {bookedNow, freeFrom, nextOwn}: when the reader may next take the rig's controls. */
  nextChance: (rig, opts) => request("GET", `/api/rigs/${enc(rig)}/next-chance`, undefined, opts),
  /** A course's analytics; query: "?from=ISO&to=ISO" or "" (the course's whole life). */
  analytics: (name, query, opts) => request("GET", `/api/courses/${enc(name)}/analytics${query}`, undefined, opts),
  /** Where a course's analytics table downloads as CSV (table: "students" or "rigs"). */
  analyticsCsvUrl: (name, table, query) => `/api/courses/${enc(name)}/analytics/${enc(table)}.csv${query}`,
};
