// @ts-check
// Assignments (#10 item 4). A teacher sets an experiment for a course (rig,
// methods from the registry, deadline, tolerances), edits it, reads the
// hand-ins and downloads the grades (CSV). A student reads the assignment,
// hands in one of their finished runs on its rig with their Ks, Ts and θ,
// and reads the mark and the feedback, check by check, in their language.

import { api, spreadsheetUrl } from "../api.js";
import { announce, h, localInput, setText, when } from "../dom.js";
import { formatDecimal, formatNumber, t } from "../i18n.js";
import { methods } from "../methods.js";
import { methodTitle } from "../runspec.js";
import { parseDecimal } from "../validate.js";
import { gradingTools, handedInBy, myTerms } from "./grading.js";
import { rigTitle } from "../shapes.js";

const enc = encodeURIComponent;

/** The quantities a student answers, and their names on the page. */
const QUANTITY = { K: "assign.qK", tau: "assign.qTau", theta: "assign.qTheta" };
/** What an answer was checked against. */
const BASIS = { reference: "assign.basisReference", run: "assign.basisRun" };
/** A check's verdict. */
const VERDICT = { pass: "assign.pass", fail: "assign.fail", not_judged: "assign.notJudged" };
/** A hand-in's state in the grades. */
const STATE = { marked: "assign.stateMarked", review: "assign.stateReview", missing: "assign.stateMissing" };

/** @param {number | null | undefined} v */
function num(v) {
  return typeof v === "number" && Number.isFinite(v) ? formatNumber(v, { maximumSignificantDigits: 6 }) : "–";
}

/** A stored fraction as the percentage a teacher typed (7, not 7.000000000000001). @param {number} v */
function percent(v) {
  return formatDecimal(Number((100 * v).toPrecision(12)));
}

/**
 * A check's tolerance in the reader's number format (the stored text if the
 * hand-in predates the stored tolerances).
 * @param {any} c  a check
 * @param {any} tol  the assessment's tolerances
 */
function tolText(c, tol) {
  const value = tol?.[c.quantity];
  if (typeof value !== "number") return String(c.tolerance);
  return c.quantity === "theta" ? t("assign.tolSeconds", { value: num(value) }) : t("assign.tolPercent", { value: num(100 * value) });
}

/** @param {any} s  a hand-in: its mark out of its maximum, or why there is none */
function markText(s) {
  return s.mark === null || s.mark === undefined ? t("assign.noMark") : t("assign.mark", { mark: num(s.mark), max: num(s.max) });
}

/**
 * @param {HTMLElement} main
 * @param {{params: string[]}} route
 * @param {any} ctx
 */
export function mount(main, { params }, ctx) {
  let alive = true;
  const error = h("p", { class: "error", id: "assign-error", role: "alert" });
  const id = params[0];
  const done = () => alive;
  if (id) {
    showOne(main, Number(id), ctx, error, done).catch((err) => setText(error, err.message));
  } else {
    showList(main, ctx, error, done).catch((err) => setText(error, err.message));
  }
  return () => {
    alive = false;
  };
}

/**
 * @param {HTMLElement} main
 * @param {any} ctx
 * @param {HTMLElement} error
 * @param {() => boolean} alive
 */
async function showList(main, ctx, error, alive) {
  const list = h("ul", { id: "assign-list" });
  main.append(h("h1", null, t("nav.assignments")), h("p", { class: "lede" }, t("assign.lede")), error, list);
  const all = await api.assignments();
  if (!alive()) return;
  list.replaceChildren(
    ...(all.length === 0
      ? [h("li", { class: "muted" }, t("assign.none"))]
      : all.map((a) =>
          h(
            "li",
            null,
            h("a", { href: `#/assignments/${enc(a.id)}`, "data-assignment": a.id }, a.title),
            " ",
            a.draft ? h("span", { class: "badge", "data-draft": a.id }, t("assign.draft")) : "",
            a.draft ? " " : "",
            h("span", { class: "muted" }, t("assign.due", { course: a.courseTitle, deadline: when(a.deadline) })),
          ),
        )),
  );
  if (ctx.user?.role !== "teacher") return;
  const courses = await api.courses();
  const rigs = await api.rigs();
  if (!alive()) return;
  main.append(
    assignmentForm(null, courses, rigs, async (course, body) => {
      const made = await api.createAssignment(course, body);
      announce(t("assign.created", { title: made.title }));
      ctx.navigate(`/assignments/${made.id}`);
    }),
  );
}

/**
 * The teacher's form, empty or with an assignment to change.
 * @param {any} current
 * @param {any[]} courses
 * @param {any[]} rigs
 * @param {(course: string, body: any) => Promise<void>} onSave
 */
function assignmentForm(current, courses, rigs, onSave) {
  const error = h("p", { class: "error", id: "assign-form-error", role: "alert" });
  const course = h(
    "select",
    { id: "assign-course", disabled: current !== null },
    courses.map((c) => h("option", { value: c.name }, c.title)),
  );
  if (current) course.replaceChildren(h("option", { value: current.course }, current.courseTitle));
  const title = h("input", { id: "assign-title", maxlength: "200", required: true, autocomplete: "off", value: current?.title ?? "" });
  const instructions = h("textarea", { id: "assign-instructions", rows: "4", maxlength: "20000" });
  instructions.value = current?.instructions ?? "";
  const rig = h("select", { id: "assign-rig" }, rigs.map((r) => h("option", { value: r.id }, rigTitle(r))));
  if (current) rig.value = current.rig;
  const boxes = methods().map((m) =>
    h(
      "label",
      { class: "check" },
      h("input", { type: "checkbox", name: "method", value: m.name, checked: current ? current.methods.includes(m.name) : m.name === "lsm" }),
      " ",
      methodTitle(m.name),
    ),
  );
  const deadline = h("input", { id: "assign-deadline", type: "datetime-local", required: true, value: current ? localInput(current.deadline) : "" });
  const tolK = h("input", { id: "assign-tol-k", inputmode: "decimal", value: percent(current?.tolerance.K ?? 0.1) });
  const tolTau = h("input", { id: "assign-tol-tau", inputmode: "decimal", value: percent(current?.tolerance.tau ?? 0.1) });
  const tolTheta = h("input", { id: "assign-tol-theta", inputmode: "decimal", value: current?.tolerance.theta === null || current?.tolerance.theta === undefined ? "" : formatDecimal(current.tolerance.theta) });
  const save = h("button", { type: "submit", class: "primary" }, t(current ? "assign.save" : "assign.create"));
  const form = h(
    "form",
    { class: "card", id: "assign-form", novalidate: true, "aria-describedby": "assign-form-error" },
    h("h2", null, t(current ? "assign.editHeading" : "assign.newHeading")),
    h("div", { class: "field" }, h("label", { for: "assign-course" }, t("assign.course")), course),
    h("div", { class: "field" }, h("label", { for: "assign-title" }, t("assign.titleLabel")), title),
    h("div", { class: "field" }, h("label", { for: "assign-instructions" }, t("assign.instructions")), instructions),
    h("div", { class: "field" }, h("label", { for: "assign-rig" }, t("assign.rig")), rig),
    h("fieldset", null, h("legend", null, t("assign.methods")), ...boxes),
    h("div", { class: "field" }, h("label", { for: "assign-deadline" }, t("assign.deadline")), deadline),
    h("div", { class: "field" }, h("label", { for: "assign-tol-k" }, t("assign.tolK")), tolK),
    h("div", { class: "field" }, h("label", { for: "assign-tol-tau" }, t("assign.tolTau")), tolTau),
    h("div", { class: "field" }, h("label", { for: "assign-tol-theta" }, t("assign.tolTheta")), tolTheta),
    error,
    save,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    const chosen = [...form.querySelectorAll("input[name=method]:checked")].map((b) => /** @type {HTMLInputElement} */ (b).value);
    const k = parseDecimal(tolK.value);
    const tau = parseDecimal(tolTau.value);
    const theta = tolTheta.value.trim() === "" ? null : parseDecimal(tolTheta.value);
    const due = new Date(deadline.value);
    if (!title.value.trim() || chosen.length === 0 || Number.isNaN(due.getTime())) {
      setText(error, t("assign.missing"));
      return;
    }
    if (k === null || tau === null || (tolTheta.value.trim() !== "" && theta === null)) {
      setText(error, t("assign.badTolerance"));
      return;
    }
    const body = {
      title: title.value.trim(),
      instructions: instructions.value,
      rig: rig.value,
      methods: chosen,
      deadline: due.toISOString(),
      tolerance: { K: k / 100, tau: tau / 100, theta },
    };
    save.disabled = true;
    try {
      await onSave(course.value, body);
    } catch (err) {
      setText(error, err.message);
    } finally {
      save.disabled = false;
    }
  });
  return form;
}

/**
 * One assignment: for a teacher, its form and hand-ins; for a student, the hand-in.
 * @param {HTMLElement} main
 * @param {number} id
 * @param {any} ctx
 * @param {HTMLElement} error
 * @param {() => boolean} alive
 */
async function showOne(main, id, ctx, error, alive) {
  const a = await api.assignment(id);
  if (!alive()) return;
  ctx.setTitle(a.title);
  const tol = a.tolerance;
  const details = h(
    "dl",
    { id: "assign-details" },
    h("dt", null, t("assign.course")),
    h("dd", null, a.courseTitle),
    h("dt", null, t("assign.rig")),
    h("dd", null, h("a", { href: `#/rig/${enc(a.rig)}` }, a.rig)),
    h("dt", null, t("assign.methods")),
    h("dd", null, a.methods.map(methodTitle).join(", ")),
    h("dt", null, t("assign.deadline")),
    h("dd", null, when(a.deadline)),
    h("dt", null, t("assign.tolerances")),
    h("dd", null, t("assign.tolText", { k: num(100 * tol.K), tau: num(100 * tol.tau) }), tol.theta === null ? "" : `, ${t("assign.tolThetaText", { theta: num(tol.theta) })}`),
  );
  main.append(
    h("h1", null, a.title),
    h("p", null, h("a", { href: "#/assignments" }, t("assign.back"))),
    error,
    details,
    h("p", { class: "instructions", id: "assign-instructions-text" }, a.instructions),
  );
  if (ctx.user?.role === "teacher") {
    if (a.draft) main.append(publishBox(a, ctx));
    const rigs = await api.rigs();
    const hand = h("div", { class: "table-wrap", id: "submissions", tabindex: "0", role: "region", "aria-label": t("assign.submissions") });
    const grades = h("a", { id: "grades-link", href: api.gradesUrl(a.course), download: `grades-${a.course}.csv` }, t("assign.grades"));
    const sheet = h("a", { id: "grades-sheet-link", href: spreadsheetUrl(api.gradesUrl(a.course)), download: `grades-${a.course}.csv` }, t("csv.spreadsheet"));
    main.append(
      h("h2", null, t("assign.submissions")),
      h("p", null, grades, " · ", sheet),
      hand,
      assignmentForm(a, [], rigs, async (_course, body) => {
        await api.updateAssignment(a.id, body);
        announce(t("assign.saved"));
        ctx.navigate(`/assignments/${a.id}`);
      }),
    );
    const all = await api.submissions(a.id);
    if (alive()) hand.replaceChildren(submissionsTable(all));
    if (!a.draft && alive()) hand.after(await gradingTools(a, alive));
    return;
  }
  const result = h("section", { id: "handin-result", "aria-live": "polite" });
  main.append(myTerms(a), await handInForm(a, ctx, result), result);
  if (a.mine.length > 0) result.replaceChildren(feedback(a.mine[0]), history(a.mine));
}

/**
 * @param {any} a
 * @param {any} ctx
 * @param {HTMLElement} result
 */
async function handInForm(a, ctx, result) {
  const error = h("p", { class: "error", id: "handin-error", role: "alert" });
  const runs = (await api.runs(`?rig=${enc(a.rig)}&user=${enc(ctx.user.username)}`)).filter((r) => r.status === "finished");
  const run = h(
    "select",
    { id: "handin-run" },
    runs.map((r) => h("option", { value: r.id }, t("assign.runOption", { run: r.id, started: when(r.startedAt) }))),
  );
  const k = h("input", { id: "handin-k", inputmode: "decimal", autocomplete: "off" });
  const tau = h("input", { id: "handin-tau", inputmode: "decimal", autocomplete: "off" });
  const theta = h("input", { id: "handin-theta", inputmode: "decimal", autocomplete: "off" });
  const conclusion = h("textarea", { id: "handin-conclusion", rows: "3", maxlength: "4000" });
  const send = h("button", { type: "submit", class: "primary", disabled: runs.length === 0 }, t("assign.handIn"));
  const form = h(
    "form",
    { class: "card", id: "handin-form", novalidate: true, "aria-describedby": "handin-error" },
    h("h2", null, t("assign.handInHeading")),
    runs.length === 0 ? h("p", { class: "muted" }, t("assign.noRuns")) : "",
    h("div", { class: "field" }, h("label", { for: "handin-run" }, t("assign.run")), run),
    h("div", { class: "field" }, h("label", { for: "handin-k" }, t("assign.answerK")), k),
    h("div", { class: "field" }, h("label", { for: "handin-tau" }, t("assign.answerTau")), tau),
    h("div", { class: "field" }, h("label", { for: "handin-theta" }, t("assign.answerTheta")), theta),
    h("div", { class: "field" }, h("label", { for: "handin-conclusion" }, t("assign.conclusion")), conclusion),
    error,
    send,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    const K = parseDecimal(k.value);
    const T = parseDecimal(tau.value);
    const th = theta.value.trim() === "" ? null : parseDecimal(theta.value);
    if (K === null || T === null || (theta.value.trim() !== "" && th === null)) {
      setText(error, t("assign.badAnswer"));
      return;
    }
    send.disabled = true;
    try {
      const made = await api.handIn(a.id, { runId: Number(run.value), K, tau: T, theta: th, conclusion: conclusion.value });
      announce(markText(made));
      const now = await api.assignment(a.id);
      result.replaceChildren(feedback(made), history(now.mine));
    } catch (err) {
      setText(error, err.message);
    } finally {
      send.disabled = false;
    }
  });
  return form;
}

/** The mark and the feedback of one hand-in, check by check. @param {any} s */
function feedback(s) {
  const rows = s.assessment.checks.map((/** @type {any} */ c) =>
    h(
      "tr",
      { "data-check": `${c.quantity}-${c.basis}`, "data-verdict": c.verdict },
      h("th", { scope: "row" }, t(QUANTITY[c.quantity])),
      h("td", null, t(BASIS[c.basis]), c.method ? ` (${String(c.method).toUpperCase()})` : ""),
      h("td", { class: "num" }, num(c.answer)),
      h("td", { class: "num" }, num(c.target)),
      h("td", null, tolText(c, s.assessment.tolerances)),
      h("td", null, t(VERDICT[c.verdict])),
      h("td", null, why(c, tolText(c, s.assessment.tolerances))),
    ),
  );
  const head = ["assign.colQuantity", "assign.colBasis", "assign.colYours", "assign.colTarget", "assign.colTolerance", "assign.colVerdict", "assign.colWhy"].map((key) => h("th", { scope: "col" }, t(key)));
  const untrusted = s.assessment.identified.filter((/** @type {any} */ i) => !i.trusted);
  return h(
    "div",
    { class: "card", id: "feedback" },
    h("h2", null, t("assign.feedbackHeading")),
    h("p", { "data-testid": "mark", class: "mark" }, markText(s)),
    s.late ? h("p", { class: "warning", "data-testid": "late" }, t("assign.late")) : "",
    s.handedInBy ? h("p", { class: "muted", "data-testid": "handed-in-by" }, t("grading.handedInBy", { name: s.handedInBy })) : "",
    // A lab group mate's run too: the run policy lets the group read the runs it hands in.
    s.runId ? h("p", null, t("assign.runHandedIn"), " ", h("a", { href: `#/runs/${enc(s.runId)}`, "data-testid": "handed-in-run" }, t("runs.label", { run: s.runId }))) : "",
    ...untrusted.map((/** @type {any} */ i) => h("p", { class: "warning" }, t("assign.untrusted", { method: String(i.method).toUpperCase() }))),
    ...s.assessment.identified
      .filter((/** @type {any} */ i) => typeof i.fit === "number")
      .map((/** @type {any} */ i) => h("p", { class: "muted" }, t("assign.fit", { method: String(i.method).toUpperCase(), fit: num(i.fit) }))),
    h(
      "div",
      { class: "table-wrap", tabindex: "0", role: "region", "aria-label": t("assign.feedbackHeading") },
      h("table", { class: "runs" }, h("caption", { class: "visually-hidden" }, t("assign.feedbackHeading")), h("thead", null, h("tr", null, head)), h("tbody", null, rows)),
    ),
  );
}

/**
 * Why a check passed or failed, in the reader's language.
 * @param {any} c
 * @param {string} tolerance
 */
function why(c, tolerance) {
  if (c.verdict === "not_judged") return t("assign.whyNotJudged");
  if (c.answer === null) return t("assign.whyNoAnswer");
  if (c.verdict === "pass") return t("assign.whyPass", { tolerance });
  return t("assign.whyFail", { tolerance });
}

/** The student's earlier hand-ins (newest first). @param {any[]} mine */
function history(mine) {
  if (mine.length < 2) return "";
  return h(
    "div",
    null,
    h("h3", null, t("assign.history")),
    h(
      "ul",
      { id: "handin-history" },
      mine.map((s) => h("li", null, t("assign.historyItem", { at: when(s.submittedAt), mark: markText(s) }), s.late ? ` (${t("assign.lateShort")})` : "", handedInBy(s))),
    ),
  );
}

/** The teacher's table of hand-ins. @param {any[]} all */
function submissionsTable(all) {
  if (all.length === 0) return h("p", { class: "muted" }, t("assign.noSubmissions"));
  const head = ["assign.colStudent", "assign.colSubmitted", "assign.colRun", "assign.colMark", "assign.colState", "assign.colLate"].map((key) => h("th", { scope: "col" }, t(key)));
  const rows = all.map((s) =>
    h(
      "tr",
      { "data-student": s.student, "data-current": String(s.current) },
      h("td", null, s.displayName ? `${s.displayName} (${s.student})` : s.student, handedInBy(s)),
      h("td", null, when(s.submittedAt)),
      h("td", null, s.runId ? h("a", { href: `#/runs/${enc(s.runId)}` }, t("runs.label", { run: s.runId })) : "–"),
      h("td", null, markText(s)),
      h("td", null, t(STATE[s.state] ?? "assign.stateReview"), s.current ? "" : ` (${t("assign.replaced")})`),
      h("td", null, s.late ? t("assign.lateShort") : ""),
    ),
  );
  return h("table", { class: "runs" }, h("caption", { class: "visually-hidden" }, t("assign.submissions")), h("thead", null, h("tr", null, head)), h("tbody", null, rows));
}

/**
 * A draft (copied from last term): its students do not see it until it is published.
 * @param {any} a
 * @param {any} ctx
 */
function publishBox(a, ctx) {
  const out = h("p", { role: "status", id: "assign-publish-result" });
  const publish = h("button", { type: "button", class: "primary", id: "assign-publish" }, t("assign.publish"));
  publish.addEventListener("click", async () => {
    publish.disabled = true;
    try {
      await api.publishAssignment(a.id);
      announce(t("assign.published"));
      ctx.navigate(`/assignments/${a.id}`);
    } catch (err) {
      setText(out, err.message);
      publish.disabled = false;
    }
  });
  return h("section", { class: "card", id: "assign-draft" }, h("p", null, t("assign.draftHelp")), publish, out);
}
