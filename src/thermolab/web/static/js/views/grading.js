// @ts-check
// A teacher's grading tools on an assignment's page (#24 item 7), and what a
// student reads of them. The teacher sees each student's standing (final
// mark with the automatic one and the comment beside it, own deadline, lab
// group), overrides a mark with a comment, extends the deadline for one
// student, and forms or removes the course's lab groups. A student reads
// their extended deadline, their group and their teacher's mark and comment.

import { api } from "../api.js";
import { announce, h, localInput, setText, when } from "../dom.js";
import { formatNumber, t } from "../i18n.js";
import { parseDecimal } from "../validate.js";

/** The highest mark (the server's MARK_MAX). */
const MARK_MAX = 10;

/** @param {number | null | undefined} v */
function num(v) {
  return typeof v === "number" && Number.isFinite(v) ? formatNumber(v, { maximumSignificantDigits: 4 }) : "–";
}

/** @param {string} username @param {string | null | undefined} display */
function person(username, display) {
  return display ? `${display} (${username})` : username;
}

/**
 * The teacher's tools: standings, override, extension, groups.
 * @param {any} a  the assignment
 * @param {() => boolean} alive
 * @returns {Promise<HTMLElement>}
 */
export async function gradingTools(a, alive) {
  const table = h("div", { class: "table-wrap", id: "standings", tabindex: "0", role: "region", "aria-label": t("grading.standings") });
  const groupList = h("ul", { id: "group-list" });
  const section = h("section", { id: "grading-tools" }, h("h2", null, t("grading.standings")), table);
  /** @type {any[]} */
  let students = [];
  const refresh = async () => {
    const [rows, groups] = await Promise.all([api.standings(a.id), api.groups(a.course)]);
    if (!alive()) return;
    students = rows;
    table.replaceChildren(standingsTable(rows));
    groupList.replaceChildren(...groupItems(a, groups, refresh));
    for (const select of section.querySelectorAll("select[data-students]")) fillStudents(/** @type {HTMLSelectElement} */ (select), rows);
    const boxes = section.querySelector("#group-members");
    if (boxes) boxes.replaceChildren(...rows.filter((s) => !s.group).map((s) => h("label", { class: "check" }, h("input", { type: "checkbox", name: "group-member", value: s.student }), " ", person(s.student, s.displayName))));
  };
  section.append(overrideForm(a, refresh), extendForm(a, () => students, refresh), groupsBox(a, groupList, refresh));
  await refresh();
  return section;
}

/** @param {HTMLSelectElement} select @param {any[]} rows */
function fillStudents(select, rows) {
  const chosen = select.value;
  select.replaceChildren(...rows.map((s) => h("option", { value: s.student }, person(s.student, s.displayName))));
  if (rows.some((s) => s.student === chosen)) select.value = chosen;
}

/** @param {any[]} rows */
function standingsTable(rows) {
  if (rows.length === 0) return h("p", { class: "muted" }, t("grading.noStudents"));
  const head = ["assign.colStudent", "grading.colGroup", "grading.colDeadline", "assign.colMark", "grading.colAutomatic", "grading.colComment"].map((key) => h("th", { scope: "col" }, t(key)));
  const body = rows.map((s) =>
    h(
      "tr",
      { "data-student": s.student, "data-overridden": String(s.overridden), "data-extended": String(s.extended) },
      h("td", null, person(s.student, s.displayName)),
      h("td", null, s.group ?? "–"),
      h("td", null, when(s.deadline), s.extended ? ` (${t("grading.extendedShort")})` : ""),
      h("td", { class: "num", "data-testid": "final-mark" }, s.mark === null ? t(s.state === "missing" ? "assign.stateMissing" : "assign.stateReview") : t("assign.mark", { mark: num(s.mark), max: num(s.max) })),
      h("td", { class: "num" }, num(s.automaticMark)),
      h("td", null, s.comment),
    ),
  );
  return h("table", { class: "runs" }, h("caption", { class: "visually-hidden" }, t("grading.standings")), h("thead", null, h("tr", null, head)), h("tbody", null, body));
}

/**
 * A small form of the tools: a heading, fields, a status line and its buttons.
 * @param {string} id
 * @param {string} heading
 * @param {HTMLElement[]} fields
 * @param {HTMLElement[]} buttons
 */
function toolForm(id, heading, fields, buttons) {
  const out = h("p", { role: "status", id: `${id}-result` });
  const form = h("form", { class: "card", id, novalidate: true }, h("h3", null, heading), ...fields, h("p", null, ...buttons), out);
  return { form, out };
}

/**
 * Override a student's mark with a comment, or remove the override.
 * @param {any} a
 * @param {() => Promise<void>} refresh
 */
function overrideForm(a, refresh) {
  const student = h("select", { id: "override-student", "data-students": "" });
  const mark = h("input", { id: "override-mark", inputmode: "decimal", autocomplete: "off" });
  const comment = h("textarea", { id: "override-comment", rows: "2", maxlength: "2000" });
  const save = h("button", { type: "submit", class: "primary" }, t("grading.overrideSave"));
  const remove = h("button", { type: "button", id: "override-remove" }, t("grading.overrideRemove"));
  const { form, out } = toolForm(
    "override-form",
    t("grading.overrideHeading"),
    [
      h("div", { class: "field" }, h("label", { for: "override-student" }, t("grading.student")), student),
      h("div", { class: "field" }, h("label", { for: "override-mark" }, t("grading.markLabel", { max: num(MARK_MAX) })), mark),
      h("div", { class: "field" }, h("label", { for: "override-comment" }, t("grading.comment")), comment),
    ],
    [save, remove],
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const value = parseDecimal(mark.value);
    if (value === null || value < 0 || value > MARK_MAX || !comment.value.trim()) {
      setText(out, t("grading.badMark", { max: num(MARK_MAX) }));
      return;
    }
    await act(out, save, async () => {
      await api.overrideMark(a.id, student.value, { mark: value, comment: comment.value.trim() });
      await refresh();
      return t("grading.overridden", { student: student.value, mark: num(value) });
    });
  });
  remove.addEventListener("click", () =>
    act(out, remove, async () => {
      await api.removeOverride(a.id, student.value);
      await refresh();
      return t("grading.overrideRemoved", { student: student.value });
    }),
  );
  return form;
}

/**
 * Extend the deadline for one student, or take the extension back.
 * @param {any} a
 * @param {() => any[]} students
 * @param {() => Promise<void>} refresh
 */
function extendForm(a, students, refresh) {
  const student = h("select", { id: "extend-student", "data-students": "" });
  const deadline = h("input", { id: "extend-deadline", type: "datetime-local", value: localInput(a.deadline) });
  const save = h("button", { type: "submit", class: "primary" }, t("grading.extendSave"));
  const remove = h("button", { type: "button", id: "extend-remove" }, t("grading.extendRemove"));
  const { form, out } = toolForm(
    "extend-form",
    t("grading.extendHeading"),
    [
      h("div", { class: "field" }, h("label", { for: "extend-student" }, t("grading.student")), student),
      h("div", { class: "field" }, h("label", { for: "extend-deadline" }, t("grading.newDeadline")), deadline),
    ],
    [save, remove],
  );
  student.addEventListener("change", () => {
    const row = students().find((s) => s.student === student.value);
    if (row) deadline.value = localInput(row.deadline);
  });
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const due = new Date(deadline.value);
    if (!student.value || Number.isNaN(due.getTime())) {
      setText(out, t("grading.badDeadline"));
      return;
    }
    await act(out, save, async () => {
      const made = await api.extendDeadline(a.id, student.value, { deadline: due.toISOString() });
      await refresh();
      return t("grading.extended", { student: made.student, deadline: when(made.deadline) });
    });
  });
  remove.addEventListener("click", () =>
    act(out, remove, async () => {
      await api.removeExtension(a.id, student.value);
      await refresh();
      return t("grading.extensionRemoved", { student: student.value });
    }),
  );
  return form;
}

/**
 * The course's lab groups: the list, and a form to form one.
 * @param {any} a
 * @param {HTMLElement} list
 * @param {() => Promise<void>} refresh
 */
function groupsBox(a, list, refresh) {
  const name = h("input", { id: "group-name", maxlength: "64", autocomplete: "off" });
  const boxes = h("div", { id: "group-members" });
  const save = h("button", { type: "submit", class: "primary" }, t("grading.groupCreate"));
  const { form, out } = toolForm(
    "group-form",
    t("grading.groupsHeading"),
    [
      h("p", { class: "muted" }, t("grading.groupsHelp")),
      list,
      h("div", { class: "field" }, h("label", { for: "group-name" }, t("grading.groupName")), name),
      h("fieldset", null, h("legend", null, t("grading.groupMembers")), boxes),
    ],
    [save],
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const members = [...boxes.querySelectorAll("input:checked")].map((b) => /** @type {HTMLInputElement} */ (b).value);
    if (!name.value.trim() || members.length < 2) {
      setText(out, t("grading.badGroup"));
      return;
    }
    await act(out, save, async () => {
      const made = await api.createGroup(a.course, { name: name.value.trim(), members });
      name.value = "";
      await refresh();
      return t("grading.groupCreated", { name: made.name });
    });
  });
  return form;
}

/**
 * @param {any} a
 * @param {any[]} groups
 * @param {() => Promise<void>} refresh
 */
function groupItems(a, groups, refresh) {
  if (groups.length === 0) return [h("li", { class: "muted" }, t("grading.noGroups"))];
  return groups.map((g) => {
    const out = h("span", { role: "status" });
    const remove = h("button", { type: "button", "aria-label": t("grading.groupRemoveLabel", { name: g.name }) }, t("grading.groupRemove"));
    remove.addEventListener("click", () =>
      act(out, remove, async () => {
        await api.removeGroup(a.course, g.id);
        announce(t("grading.groupRemoved", { name: g.name }));
        await refresh();
        return "";
      }),
    );
    const names = g.members.map((/** @type {any} */ m) => person(m.username, m.displayName)).join(", ");
    return h("li", { "data-group": g.name }, t("grading.groupItem", { name: g.name, members: names }), " ", remove, " ", out);
  });
}

/**
 * Run a change with its button held down; say what happened or why not.
 * @param {HTMLElement} out
 * @param {HTMLButtonElement} button
 * @param {() => Promise<string>} change  resolves to what to say
 */
async function act(out, button, change) {
  setText(out, "");
  button.disabled = true;
  try {
    const said = await change();
    if (said) {
      setText(out, said);
      announce(said);
    }
  } catch (err) {
    setText(out, /** @type {Error} */ (err).message);
  } finally {
    button.disabled = false;
  }
}

/**
 * What a student reads of the tools: their own deadline, group, and teacher's mark.
 * @param {any} a  the assignment, as the student gets it
 * @returns {HTMLElement | ""}
 */
export function myTerms(a) {
  const lines = [];
  if (a.extendedDeadline) lines.push(h("p", { "data-testid": "extended" }, t("grading.yourDeadline", { deadline: when(a.extendedDeadline) })));
  if (a.group) lines.push(h("p", { "data-testid": "group" }, t("grading.yourGroup", { name: a.group.name, members: a.group.members.join(", ") })));
  if (a.override) {
    lines.push(
      h("p", { class: "mark", "data-testid": "override" }, t("grading.yourMark", { mark: num(a.override.mark), max: num(a.override.max) })),
      h("p", { "data-testid": "override-comment" }, t("grading.teacherComment", { comment: a.override.comment })),
    );
    if (a.mine.length > 0 && typeof a.mine[0].mark === "number") lines.push(h("p", { class: "muted" }, t("grading.automaticMark", { mark: num(a.mine[0].mark) })));
  }
  return lines.length === 0 ? "" : h("section", { class: "card", id: "my-terms" }, ...lines);
}

/** Who handed a group's hand-in in, when it was not the student. @param {any} s */
export function handedInBy(s) {
  return s.handedInBy ? ` (${t("grading.handedInBy", { name: s.handedInBy })})` : "";
}
