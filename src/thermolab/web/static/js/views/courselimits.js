// @ts-check
// A course's limits during its booked slots (GET/PUT /api/courses/{course}/settings):
// for each setting a course may override (turn limit, idle limit, longest run) a
// box "set for this course" and its value; unticked, the rig's value applies. The
// form is built from the server's declarations and saved with the version it
// was read at (a save in between is refused, and the form reloads).

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { formatDecimal, t } from "../i18n.js";
import { checkNumber, rangeText } from "../validate.js";
import { TEXTS } from "./settings.js";

/**
 * The limits of course ``name``, as a section of the course page; it loads itself.
 * @param {string} name
 * @returns {HTMLElement}
 */
export function courseLimitsSection(name) {
  const body = h("div", null, h("p", { class: "muted" }, t("app.loading")));
  const box = h(
    "section",
    { class: "course-limits", "aria-labelledby": "course-limits-heading" },
    h("h3", { id: "course-limits-heading" }, t("courseLimits.heading")),
    h("p", { class: "muted", id: "course-limits-rule" }, t("courseLimits.rule")),
    body,
  );
  const load = () =>
    api
      .courseSettings(name)
      .then((data) => body.replaceChildren(limitsForm(name, data, load)))
      .catch((err) => body.replaceChildren(h("p", { class: "error", role: "alert" }, err.message)));
  void load();
  return box;
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
    const [labelKey, helpKey] = TEXTS[/** @type {keyof typeof TEXTS} */ (s.name)] ?? [null, null];
    const label = labelKey ? t(labelKey) : s.name;
    const spec = { label, min: s.minimum, max: s.maximum, unit: "s" };
    const own = h("input", { type: "checkbox", id: `${id}-own`, checked: s.overridden });
    const el = h("input", {
      id,
      name: s.name,
      value: s.value === null || s.value === undefined ? "" : formatDecimal(s.value),
      inputmode: "decimal",
      autocomplete: "off",
      disabled: !s.overridden,
      "aria-describedby": `${id}-hint`,
    });
    own.addEventListener("change", () => {
      el.disabled = !own.checked;
    });
    const hints = [helpKey ? t(helpKey) : s.help, t("settings.range", { range: rangeText(spec) })];
    if (s.nullable) hints.push(t("settings.emptyAllowed"));
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
      if (el.value.trim() === "" && setting.nullable) {
        values[key] = null;
        continue;
      }
      const r = checkNumber(el.value, spec);
      if (!r.ok) {
        el.setAttribute("aria-invalid", "true");
        setText(message, r.error);
        el.focus();
        return;
      }
      values[key] = r.value;
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
