// @ts-check
// A teacher's courses: create one, upload its class list (CSV) and read the
// report (each new student's one-time password, or every bad line), see the
// roster, show or renew the enrolment code, reset a student's password, add a
// teaching assistant; at the end of the term, close the course and copy it to
// the next one (endOfTermSection in term.js).

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { serverMessage, t } from "../i18n.js";
import { courseLimitsSection } from "./courselimits.js";
import { endOfTermSection } from "./term.js";
import { rigTitle } from "../shapes.js";

/**
 * @param {HTMLElement} main
 * @param {{query: URLSearchParams}} route
 * @param {any} ctx
 */
export function mount(main, { query }, ctx) {
  if (ctx.user?.role !== "teacher") {
    main.append(h("h1", null, t("nav.courses")), h("p", { class: "error" }, t("courses.only")));
    return null;
  }
  let alive = true;
  const error = h("p", { class: "error", id: "course-error", role: "alert" });
  const list = h("ul", { id: "course-list" });
  const detail = h("section", { class: "card", id: "course-detail", hidden: true, "aria-live": "polite" });
  const name = h("input", { id: "course-name", name: "name", maxlength: "64", required: true, autocomplete: "off", autocapitalize: "none" });
  const title = h("input", { id: "course-title", name: "title", maxlength: "200", required: true, autocomplete: "off" });
  const create = h("button", { type: "submit", class: "primary" }, t("courses.create"));
  const form = h(
    "form",
    { class: "card", id: "course-form", novalidate: true, "aria-describedby": "course-error" },
    h("h2", null, t("courses.newHeading")),
    h("div", { class: "field" }, h("label", { for: "course-name" }, t("courses.name")), name),
    h("div", { class: "field" }, h("label", { for: "course-title" }, t("courses.titleLabel")), title),
    error,
    create,
  );

  async function refresh() {
    const courses = await api.courses();
    if (!alive) return;
    list.replaceChildren(
      ...(courses.length === 0
        ? [h("li", { class: "muted" }, t("courses.none"))]
        : courses.map((c) =>
            h(
              "li",
              { "data-course": c.name },
              h("a", { href: `#/courses?course=${encodeURIComponent(c.name)}` }, `${c.title} (${c.name})`),
              c.closedAt ? " " : "",
              c.closedAt ? h("span", { class: "badge", "data-closed": "true" }, t("courses.closedMark")) : "",
            ),
          )),
    );
  }

  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    if (!name.value.trim() || !title.value.trim()) {
      setText(error, t("courses.missing"));
      (name.value.trim() ? title : name).focus();
      return;
    }
    create.disabled = true;
    try {
      const made = await api.createCourse({ name: name.value.trim(), title: title.value.trim() });
      announce(t("courses.created", { course: made.title }));
      form.reset();
      ctx.navigate(`/courses?course=${encodeURIComponent(made.name)}`);
    } catch (err) {
      setText(error, err.message);
    } finally {
      create.disabled = false;
    }
  });

  main.append(h("h1", null, t("nav.courses")), h("p", { class: "lede" }, t("courses.lede")), list, form, detail);
  refresh().catch((err) => setText(error, err.message));
  const chosen = query.get("course");
  if (chosen) showCourse(detail, chosen, () => alive, ctx).catch((err) => setText(error, err.message));
  return () => {
    alive = false;
  };
}

/**
 * One course: its code, the class-list upload with its report, the roster.
 * @param {HTMLElement} box
 * @param {string} name
 * @param {() => boolean} alive
 * @param {any} ctx
 */
async function showCourse(box, name, alive, ctx) {
  const course = await api.course(name);
  if (!alive()) return;
  const code = h("code", { id: "course-code" }, course.enrolCode);
  const rotate = h("button", { type: "button", id: "course-rotate" }, t("courses.rotate"));
  const file = h("input", { id: "roster-file", type: "file", accept: ".csv,text/csv" });
  const upload = h("button", { type: "button", class: "primary", id: "roster-upload" }, t("courses.upload"));
  const report = h("div", { id: "roster-report", role: "status" });
  const roster = h("div", { class: "table-wrap", id: "roster", tabindex: "0", role: "region", "aria-label": t("courses.roster") });
  const teacherPassword = h("input", { id: "reset-current", type: "password", autocomplete: "current-password" });
  const resetOut = h("p", { id: "reset-result", role: "status" });

  async function refreshRoster() {
    const now = await api.course(name);
    if (alive()) roster.replaceChildren(rosterTable(now.members, reset));
  }

  /** @param {string} username */
  async function reset(username) {
    setText(resetOut, "");
    if (!teacherPassword.value) {
      setText(resetOut, t("courses.resetNeedsPassword"));
      teacherPassword.focus();
      return;
    }
    try {
      const made = await api.resetPassword(username, teacherPassword.value);
      resetOut.replaceChildren(t("courses.resetDone", { user: username }), " ", h("code", { id: "reset-password" }, made.temporaryPassword));
      await refreshRoster();
    } catch (err) {
      setText(resetOut, err.message);
    }
  }

  rotate.addEventListener("click", async () => {
    try {
      setText(code, (await api.rotateCode(name)).enrolCode);
      announce(t("courses.rotated"));
    } catch (err) {
      setText(report, err.message);
    }
  });
  upload.addEventListener("click", async () => {
    const chosen = file.files?.[0];
    report.replaceChildren();
    if (!chosen) {
      setText(report, t("courses.noFile"));
      file.focus();
      return;
    }
    upload.disabled = true;
    try {
      const done = await api.uploadRoster(name, await chosen.arrayBuffer());
      report.replaceChildren(importReport(done));
      await refreshRoster();
    } catch (err) {
      report.replaceChildren(badLines(err));
    } finally {
      upload.disabled = false;
    }
  });

  box.replaceChildren(
    h("h2", null, course.title),
    h("p", null, h("a", { href: `#/analytics?course=${encodeURIComponent(course.name)}`, id: "course-analytics" }, t("courses.analytics"))),
    h("p", null, t("courses.code"), " ", code, " ", rotate),
    h("p", { class: "muted" }, t("courses.codeHelp")),
    await courseRigs(name, course.rigs),
    courseLimitsSection(course.name),
    h("h3", null, t("courses.uploadHeading")),
    h("p", { class: "muted" }, t("courses.uploadHelp")),
    h("div", { class: "field" }, h("label", { for: "roster-file" }, t("courses.file")), file),
    upload,
    report,
    h("h3", null, t("courses.roster")),
    h("div", { class: "field" }, h("label", { for: "reset-current" }, t("courses.resetCurrent")), teacherPassword),
    resetOut,
    roster,
    assistantForm(name, refreshRoster),
    endOfTermSection(course, ctx),
  );
  box.hidden = false;
  roster.replaceChildren(rosterTable(course.members, reset));
}

/**
 * The rigs a course's students may use: a box per rig of the lab (none ticked: every rig).
 * @param {string} name
 * @param {string[]} chosen
 */
async function courseRigs(name, chosen) {
  const rigs = await api.rigs();
  const out = h("p", { role: "status", id: "course-rigs-result" });
  const boxes = rigs.map((/** @type {any} */ rig) => {
    const id = `course-rig-${rig.id}`;
    const box = h("input", { type: "checkbox", id, value: rig.id, checked: chosen.includes(rig.id) });
    return { box, el: h("div", { class: "field inline" }, box, h("label", { for: id }, rigTitle(rig))) };
  });
  const save = h("button", { type: "submit", id: "course-rigs-save" }, t("courses.rigsSave"));
  const form = h(
    "form",
    { id: "course-rigs", novalidate: true },
    h("fieldset", null, h("legend", null, t("courses.rigsHeading")), h("p", { class: "muted" }, t("courses.rigsHelp")), ...boxes.map((b) => b.el)),
    save,
    out,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    save.disabled = true;
    try {
      const made = await api.setCourseRigs(name, boxes.filter((b) => b.box.checked).map((b) => b.box.value));
      setText(out, made.rigs.length ? t("courses.rigsSaved", { rigs: made.rigs.join(", ") }) : t("courses.rigsAll"));
    } catch (err) {
      setText(out, err.message);
    } finally {
      save.disabled = false;
    }
  });
  return form;
}

/** @param {{created: Record<string, string>, updated: string[], unchanged: string[], encoding?: string}} done */
function importReport(done) {
  const created = Object.entries(done.created);
  const summary = h(
    "p",
    { id: "roster-summary" },
    t("courses.imported", { created: created.length, updated: done.updated.length, unchanged: done.unchanged.length }),
    " ",
    h("span", { id: "roster-encoding" }, t("courses.readAs", { encoding: done.encoding ?? "UTF-8" })),
  );
  if (created.length === 0) return summary;
  const rows = created.map(([user, pw]) => h("tr", null, h("td", null, user), h("td", null, h("code", null, pw))));
  return h(
    "div",
    null,
    summary,
    h("p", null, t("courses.passwordsOnce")),
    h(
      "table",
      { class: "runs", id: "roster-passwords" },
      h("thead", null, h("tr", null, h("th", { scope: "col" }, t("courses.colUser")), h("th", { scope: "col" }, t("courses.colPassword")))),
      h("tbody", null, rows),
    ),
  );
}

/** The server's list of bad lines (422 class_list_invalid), or its message. @param {any} err */
function badLines(err) {
  const errors = err?.body?.errors;
  if (!Array.isArray(errors) || err.body.code !== "class_list_invalid") return h("p", { class: "error" }, err.message);
  return h(
    "div",
    { class: "error", role: "alert" },
    h("p", null, err.message),
    h(
      "ul",
      { id: "roster-errors" },
      errors.map((e) => h("li", null, t("courses.badLine", { line: Number(e.loc?.[1] ?? 0), reason: problemText(e) }))),
    ),
  );
}

/**
 * One bad line's reason in the page's language: the catalogue's sentence for its
 * stable code ("error.class_list.header"), else the server's own sentence in the
 * reader's language, else its English text.
 * @param {any} problem  one of a 422 class_list_invalid's `errors`
 */
function problemText(problem) {
  const server = typeof problem.message === "string" && problem.message ? problem.message : String(problem.msg);
  const params = problem.params && typeof problem.params === "object" ? problem.params : {};
  return serverMessage(problem.type, server, params);
}

/** @type {Record<string, string>} */
const ROLE_KEYS = { teacher: "role.teacher", assistant: "role.assistant", student: "role.student" };

/**
 * A teaching assistant added by login name; the roster shown again.
 * @param {string} name  the course
 * @param {() => Promise<void>} refreshRoster
 */
function assistantForm(name, refreshRoster) {
  const user = h("input", { id: "assistant-name", name: "assistant", maxlength: "64", required: true, autocomplete: "off", autocapitalize: "none" });
  const add = h("button", { type: "submit", id: "assistant-add" }, t("courses.assistantAdd"));
  const out = h("p", { role: "status", id: "assistant-result" });
  const form = h(
    "form",
    { id: "assistant-form", novalidate: true },
    h("h3", null, t("courses.assistantHeading")),
    h("p", { class: "muted" }, t("courses.assistantHelp")),
    h("div", { class: "field" }, h("label", { for: "assistant-name" }, t("courses.assistantName")), user),
    add,
    out,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const login = user.value.trim();
    if (!login) {
      user.focus();
      return;
    }
    add.disabled = true;
    try {
      await api.addAssistant(name, login);
      setText(out, t("courses.assistantAdded", { user: login }));
      form.reset();
      await refreshRoster();
    } catch (err) {
      setText(out, err.message);
    } finally {
      add.disabled = false;
    }
  });
  return form;
}

/**
 * @param {any[]} members
 * @param {(username: string) => void} onReset
 */
function rosterTable(members, onReset) {
  const rows = members.map((m) =>
    h(
      "tr",
      { "data-member": m.username },
      h("td", null, m.username),
      h("td", null, m.displayName ?? ""),
      h("td", null, t(ROLE_KEYS[m.role] ?? "role.student")),
      h("td", null, m.mustChangePassword ? t("courses.temporary") : ""),
      h(
        "td",
        null,
        m.role === "student"
          ? h("button", { type: "button", "aria-label": t("courses.resetOne", { user: m.username }), onclick: () => onReset(m.username) }, t("courses.reset"))
          : "",
      ),
    ),
  );
  const head = ["courses.colUser", "courses.colName", "courses.colRole", "courses.colState", "courses.colActions"].map((key) => h("th", { scope: "col" }, t(key)));
  return h("table", { class: "runs" }, h("caption", { class: "visually-hidden" }, t("courses.roster")), h("thead", null, h("tr", null, head)), h("tbody", null, rows));
}
