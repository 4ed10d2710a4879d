// @ts-check
// A course's analytics (teachers): per student, time at the controls, runs,
// methods, latest results and assignments; per rig, use, queue waits, faults
// and hours powered — over a chosen window of days, with charts (each with its
// table) and both tables as CSV from the server (formula-safe cells).
//
// Every figure comes from GET /api/courses/{course}/analytics; the page only
// writes it in the reader's language (decimal comma in pt-BR, local dates).

import { api, spreadsheetUrl } from "../api.js";
import { Chart } from "../charts.js";
import { duration, h, setText, when } from "../dom.js";
import { formatNumber, t } from "../i18n.js";
import { methodTitle, runStatusText } from "../runspec.js";

/** The run statuses a student's runs are counted under, in the table's order. */
const STATUSES = ["finished", "stopped", "interrupted", "failed", "running"];

/** @param {number} seconds @param {number} [digits] */
const hours = (seconds, digits = 2) => formatNumber(seconds / 3600, { maximumFractionDigits: digits, minimumFractionDigits: digits });
/** @param {number} seconds */
const minutes = (seconds) => formatNumber(seconds / 60, { maximumFractionDigits: 1, minimumFractionDigits: 1 });
/** @param {number | null} v */
const sig = (v) => (typeof v === "number" && Number.isFinite(v) ? formatNumber(v, { maximumSignificantDigits: 6 }) : "–");

/** A local date (YYYY-MM-DD) of an instant, for a date field. @param {Date} d */
function dateField(d) {
  const pad = (n) => String(n).padStart(2, "0");
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}`;
}

/**
 * The API's query for a window of whole local days: from the first day's
 * midnight to the midnight after the last day.
 * @param {string} from  YYYY-MM-DD or ""
 * @param {string} to    YYYY-MM-DD or ""
 */
export function windowQuery(from, to) {
  const params = new URLSearchParams();
  if (from) params.set("from", new Date(`${from}T00:00:00`).toISOString());
  if (to) {
    const end = new Date(`${to}T00:00:00`);
    end.setDate(end.getDate() + 1);
    params.set("to", end.toISOString());
  }
  const text = params.toString();
  return text ? `?${text}` : "";
}

/**
 * @param {HTMLElement} main
 * @param {{query: URLSearchParams}} route
 * @param {any} ctx
 */
export function mount(main, { query }, ctx) {
  if (ctx.user?.role !== "teacher") {
    main.append(h("h1", null, t("analytics.title")), h("p", { class: "error" }, t("analytics.only")));
    return null;
  }
  const course = query.get("course") ?? "";
  const abort = new AbortController();
  /** @type {Chart[]} */
  let charts = [];
  const heading = h("h1", null, t("analytics.title"));
  const status = h("p", { class: "muted", role: "status", id: "analytics-status" }, t("app.loading"));
  const from = h("input", { id: "analytics-from", type: "date", value: query.get("from") ?? "" });
  const to = h("input", { id: "analytics-to", type: "date", value: query.get("to") ?? "" });
  const apply = h("button", { type: "submit", class: "primary" }, t("analytics.apply"));
  const form = h(
    "form",
    { class: "card", id: "analytics-window", novalidate: true },
    h("h2", null, t("analytics.window")),
    h("div", { class: "field" }, h("label", { for: "analytics-from" }, t("analytics.from")), from),
    h("div", { class: "field" }, h("label", { for: "analytics-to" }, t("analytics.to")), to),
    apply,
  );
  const body = h("div", { id: "analytics-body" });
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    const q = new URLSearchParams({ course });
    if (from.value) q.set("from", from.value);
    if (to.value) q.set("to", to.value);
    ctx.navigate(`/analytics?${q}`);
  });
  main.append(
    heading,
    h("p", null, h("a", { href: `#/courses?course=${encodeURIComponent(course)}` }, t("analytics.backToCourse"))),
    form,
    status,
    body,
  );

  (async () => {
    try {
      const q = windowQuery(from.value, to.value);
      const data = await api.analytics(course, q, { signal: abort.signal });
      setText(heading, t("analytics.heading", { course: data.title }));
      ctx.setTitle(t("analytics.heading", { course: data.title }));
      if (!from.value) from.value = dateField(new Date(data.windowFrom));
      if (!to.value) to.value = dateField(new Date(data.windowTo));
      setText(status, t("analytics.covering", { from: when(data.windowFrom), to: when(data.windowTo) }));
      charts = render(body, data, course, q);
    } catch (err) {
      if (err.name !== "AbortError") setText(status, t("analytics.failed", { error: err.message }));
    }
  })();
  return () => {
    abort.abort();
    for (const c of charts) c.destroy();
  };
}

/**
 * @param {HTMLElement} body
 * @param {any} data  AnalyticsOut
 * @param {string} course
 * @param {string} q  the window's query
 * @returns {Chart[]}
 */
function render(body, data, course, q) {
  const students = data.students;
  const rigs = data.rigs;
  const studentBox = h("section", { class: "card", id: "analytics-students", "aria-labelledby": "analytics-students-h" });
  const rigBox = h("section", { class: "card", id: "analytics-rigs", "aria-labelledby": "analytics-rigs-h" });
  const download = (table, key, id) => [
    h("a", { href: api.analyticsCsvUrl(course, table, q), download: "", class: "button", id }, t(key)),
    " ",
    h("a", { href: spreadsheetUrl(api.analyticsCsvUrl(course, table, q)), download: "", class: "button", id: `${id}-sheet` }, t("csv.spreadsheet")),
  ];
  studentBox.append(
    h("h2", { id: "analytics-students-h" }, t("analytics.students")),
    h("p", null, download("students", "analytics.csvStudents", "analytics-students-csv")),
  );
  rigBox.append(
    h("h2", { id: "analytics-rigs-h" }, t("analytics.rigs")),
    h("p", { class: "muted" }, t("analytics.rigsNote")),
    h("p", null, download("rigs", "analytics.csvRigs", "analytics-rigs-csv")),
  );
  body.replaceChildren(studentBox, rigBox);
  const charts = [];
  if (students.length === 0) {
    studentBox.append(h("p", { class: "muted" }, t("analytics.noStudents")));
  } else {
    const names = students.map((s) => s.displayName ?? s.username);
    charts.push(
      new Chart(studentBox, {
        label: t("analytics.chartTime"),
        xLabel: t("analytics.colStudent"),
        yLabel: t("analytics.minutes"),
        categories: names,
        series: [{ label: t("analytics.colTimeMinutes") }],
        source: () => [students.map((_, i) => i), students.map((s) => s.controlSeconds / 60)],
        emptyText: t("analytics.noStudents"),
      }),
      new Chart(studentBox, {
        label: t("analytics.chartRuns"),
        xLabel: t("analytics.colStudent"),
        yLabel: t("analytics.colRuns"),
        categories: names,
        series: [{ label: t("analytics.colRuns") }, { label: t("runStatus.finished") }],
        source: () => [students.map((_, i) => i), students.map((s) => s.runs), students.map((s) => s.runsByStatus.finished ?? 0)],
        emptyText: t("analytics.noStudents"),
      }),
    );
    studentBox.append(studentTable(students));
  }
  const rigNames = rigs.map((r) => r.title);
  charts.push(
    new Chart(rigBox, {
      label: t("analytics.chartUse"),
      xLabel: t("analytics.colRig"),
      yLabel: t("analytics.hours"),
      categories: rigNames,
      series: [{ label: t("analytics.colControlled") }, { label: t("analytics.colPowered") }],
      source: () => [rigs.map((_, i) => i), rigs.map((r) => r.controlSeconds / 3600), rigs.map((r) => r.poweredSeconds / 3600)],
    }),
    new Chart(rigBox, {
      label: t("analytics.chartWaits"),
      xLabel: t("analytics.colRig"),
      yLabel: t("analytics.seconds"),
      categories: rigNames,
      series: [{ label: t("analytics.colWaitMedian") }, { label: t("analytics.colWaitP90") }],
      source: () => [rigs.map((_, i) => i), rigs.map((r) => r.waits.median ?? Number.NaN), rigs.map((r) => r.waits.p90 ?? Number.NaN)],
    }),
  );
  rigBox.append(rigTable(rigs));
  return charts;
}

/** A table in its scrolling region (a phone scrolls it sideways). @param {string} label @param {HTMLElement} table */
function region(label, table) {
  return h("div", { class: "table-wrap", tabindex: "0", role: "region", "aria-label": label }, table);
}

/** @param {any[]} students */
function studentTable(students) {
  const head = [
    "analytics.colStudent",
    "analytics.colLogin",
    "analytics.colTimeMinutes",
    "analytics.colTurns",
    "analytics.colRuns",
    "analytics.colMethods",
    "analytics.colResults",
    "analytics.colAssignments",
  ].map((key) => h("th", { scope: "col" }, t(key)));
  const rows = students.map((s) =>
    h(
      "tr",
      { "data-student": s.username },
      h("th", { scope: "row" }, s.displayName ?? s.username),
      h("td", null, s.username),
      h("td", { class: "num", "data-field": "controlSeconds", "data-value": s.controlSeconds }, minutes(s.controlSeconds)),
      h("td", { class: "num", "data-field": "turns" }, formatNumber(s.turns)),
      h("td", { "data-field": "runs", "data-value": s.runs }, runsText(s)),
      h("td", { "data-field": "methods" }, s.results.map((r) => t("analytics.methodRuns", { method: methodTitle(r.method), count: r.runs })).join(", ") || "–"),
      h("td", { "data-field": "results" }, s.results.length ? h("ul", { class: "analytics-results" }, s.results.map(resultItem)) : "–"),
      h("td", { "data-field": "assignments" }, assignmentsText(s.assignments)),
    ),
  );
  return region(
    t("analytics.students"),
    h("table", { class: "runs", id: "analytics-student-table" }, h("caption", { class: "visually-hidden" }, t("analytics.students")), h("thead", null, h("tr", null, head)), h("tbody", null, rows)),
  );
}

/** "5 (finished: 3, stopped: 2)" in the reader's language. @param {any} s */
function runsText(s) {
  const parts = STATUSES.filter((k) => (s.runsByStatus[k] ?? 0) > 0).map((k) => `${runStatusText(k)}: ${formatNumber(s.runsByStatus[k])}`);
  return parts.length ? t("analytics.runsBy", { count: s.runs, parts: parts.join(", ") }) : formatNumber(0);
}

/** @param {any} r  ResultOut */
function resultItem(r) {
  return h(
    "li",
    { "data-method": r.method, "data-k": r.K ?? "", "data-trusted": String(r.trusted), class: r.trusted ? null : "not-trusted" },
    t("analytics.result", { method: methodTitle(r.method), K: sig(r.K), tau: sig(r.tau), theta: sig(r.theta) }),
    " ",
    h("span", null, t(r.trusted ? "analytics.trusted" : "analytics.notTrusted")),
  );
}

/** @param {any} a  AssignmentsOut or null */
function assignmentsText(a) {
  if (!a) return t("analytics.noAssignments");
  return t("analytics.assignments", {
    submitted: a.submitted,
    assigned: a.assigned,
    late: a.late,
    // A percentage of each assignment's maximum ("100 %" where the marks read "10 de 10").
    mark: a.meanMark === null ? "–" : formatNumber(a.meanMark / 100, { style: "percent", maximumFractionDigits: 1 }),
  });
}

/** @param {any[]} rigs */
function rigTable(rigs) {
  const head = [
    "analytics.colRig",
    "analytics.colControlled",
    "analytics.colTurns",
    "analytics.colStudents",
    "analytics.colRuns",
    "analytics.colWaitMedian",
    "analytics.colWaitP90",
    "analytics.colFaults",
    "analytics.colPowered",
  ].map((key) => h("th", { scope: "col" }, t(key)));
  const rows = rigs.map((r) =>
    h(
      "tr",
      { "data-rig": r.rig },
      h("th", { scope: "row" }, r.title),
      h("td", { class: "num", "data-field": "controlSeconds", "data-value": r.controlSeconds }, hours(r.controlSeconds)),
      h("td", { class: "num", "data-field": "turns" }, formatNumber(r.turns)),
      h("td", { class: "num", "data-field": "students" }, formatNumber(r.students)),
      h("td", { class: "num", "data-field": "runs" }, formatNumber(r.runs)),
      h("td", { class: "num", "data-field": "waitMedian", "data-value": r.waits.median ?? "" }, r.waits.count ? duration(r.waits.median) : "–"),
      h("td", { class: "num", "data-field": "waitP90", "data-value": r.waits.p90 ?? "" }, r.waits.count ? duration(r.waits.p90) : "–"),
      h("td", { "data-field": "faults" }, t("analytics.faults", { failed: r.failedRuns, interlocks: r.interlockRuns, faults: r.rigFaults })),
      h(
        "td",
        { class: "num", "data-field": "poweredSeconds", "data-value": r.poweredSeconds },
        hours(r.poweredSeconds),
        r.powerRecordedSince ? h("br") : null,
        r.powerRecordedSince ? h("small", { class: "muted" }, t("analytics.poweredSince", { since: when(r.powerRecordedSince) })) : null,
      ),
    ),
  );
  return region(
    t("analytics.rigs"),
    h("table", { class: "runs", id: "analytics-rig-table" }, h("caption", { class: "visually-hidden" }, t("analytics.rigs")), h("thead", null, h("tr", null, head)), h("tbody", null, rows)),
  );
}
