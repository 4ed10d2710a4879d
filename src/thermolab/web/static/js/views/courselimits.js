// @ts-check
// A course's limits during its booked slots (GET/PUT /api/courses/{course}/settings):
// for each setting a course may override (turn limit, idle limit, longest run) a
// box "set for this course" and its value; unticked, the rig's value applies. The
// form is built from the server's declarations and saved with the version it
// was read at (a save in between is refused, and the form reloads).

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { t } from "../i18n.js";
import { loadingSection, numberField, readNumber } from "./settings.js";

/**
 * The limits of course ``name``, as a section of the course page; it loads itself.
 * @param {string} name
 * @returns {HTMLElement}
 */
export function courseLimitsSection(name) {
  return loadingSection(
    { class: "course-limits", "aria-labelledby": "course-limits-heading" },
    [
      h("h3", { id: "course-limits-heading" }, t("courseLimits.heading")),
      h("p", { class: "muted", id: "course-limits-rule" }, t("courseLimits.rule")),
    ],
    () => api.courseSettings(name),
    (data, reload) => limitsForm(name, data, reload),
  );
}

/**
 * @param {string} name
 * @param {any} data  the server's answer
 * @param {() => Promise<unknown>} reload
 */
function limitsForm(name, data, reload) {
  const message = h("p", { class: "error", role: "alert", id: "course-limits-error" });
  /** @type {Map<string, {own: HTMLInputElement, el: HTMLInputElement, setting: any, spec: any}>} */
  const fields = new Map();
  const rows = [];
  for (const s of data.settings) {
    const id = `course-limit-${s.name}`;
    const { label, spec, el, hints } = numberField(s, id, "s", { disabled: !s.overridden });
    const own = h("input", { type: "checkbox", id: `${id}-own`, checked: s.overridden });
    own.addEventListener("change", () => {
      el.disabled = !own.checked;
    });
    fields.set(s.name, { own, el, setting: s, spec });
    rows.push(
      h(
        "fieldset",
        null,
        h("legend", null, label),
        h("div", { class: "field inline" }, own, h("label", { for: own.id }, t("courseLimits.own"))),
        h("div", { class: "field" }, h("label", { for: id }, t("courseLimits.value")), el, h("span", { class: "hint", id: `${id}-hint` }, hints.join(" "))),
      ),
    );
  }
  const save = h("button", { type: "submit", class: "primary", id: "course-limits-save" }, t("courseLimits.save"));
  const form = h(
    "form",
    { id: "course-limits", novalidate: true, "aria-describedby": message.id, "data-version": String(data.version) },
    ...rows,
    message,
    save,
    h("p", { class: "muted" }, data.updatedBy ? t("settings.savedBy", { user: data.updatedBy }) : t("courseLimits.none")),
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(message, "");
    /** @type {Record<string, number | null>} */
    const values = {};
    for (const [key, { own, el, setting, spec }] of fields) {
      el.removeAttribute("aria-invalid");
      if (!own.checked) continue;
      const value = readNumber(el, setting, spec, message);
      if (value === undefined) return;
      values[key] = value;
    }
    save.disabled = true;
    try {
      await api.saveCourseSettings(name, { version: data.version, values });
      announce(t("courseLimits.saved", { course: name }));
      await reload();
    } catch (err) {
      setText(message, err.message);
      if (err?.body?.code === "settings_changed") await reload();
    } finally {
      save.disabled = false;
    }
  });
  return form;
}
