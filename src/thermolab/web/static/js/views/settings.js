// @ts-check
// A rig's teacher settings (turn and idle limits, maximum run, cool-down, a
// twin's speed-up: only the twins the lab runs list it): the
// form is built from the server's declarations (GET /api/rigs/{rig}/settings:
// name, type, unit, range on this rig, choices, when a change applies), checked
// here with the same ranges and saved with the version it was read at (a save
// in between is refused, and the form reloads).

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { formatDecimal, t } from "../i18n.js";
import { unitSymbol } from "../quantities.js";
import { checkNumber, rangeText } from "../validate.js";

/** Catalogue keys of each declared setting: [label, help] (the course page uses them too). */
export const TEXTS = {
  control_time_limit: ["settings.controlTimeLimit", "settings.controlTimeLimitHelp"],
  idle_limit: ["settings.idleLimit", "settings.idleLimitHelp"],
  max_run_seconds: ["settings.maxRunSeconds", "settings.maxRunSecondsHelp"],
  cooldown_mode: ["settings.cooldownMode", "settings.cooldownModeHelp"],
  cooldown_tolerance: ["settings.cooldownTolerance", "settings.cooldownToleranceHelp"],
  cooldown_max_seconds: ["settings.cooldownMaxSeconds", "settings.cooldownMaxSecondsHelp"],
  cooldown_input: ["settings.cooldownInput", "settings.cooldownInputHelp"],
  twin_speedup: ["settings.twinSpeedup", "settings.twinSpeedupHelp"],
};
const APPLIES = { next_turn: "settings.appliesNextTurn", next_run: "settings.appliesNextRun", now: "settings.appliesNow" };
const CHOICES = { none: "settings.choiceNone", ambient: "settings.choiceAmbient" };

/**
 * The settings of one rig, as a card section; it loads itself.
 * @param {string} rigId
 * @returns {HTMLElement}
 */
export function settingsSection(rigId) {
  const hid = `settings-${rigId}`;
  return loadingSection(
    { class: "rig-settings", "aria-labelledby": hid, "data-settings": rigId },
    [h("h3", { id: hid }, t("settings.heading")), h("p", { class: "muted" }, t("settings.when"))],
    () => api.rigSettings(rigId),
    (data, reload) => settingsForm(rigId, data, reload),
  );
}

/**
 * A section that loads its form (a rig's settings, a course's limits): "loading",
 * then the form drawn from the server's answer, or the error; ``reload`` draws it again.
 * @param {Record<string, string>} attrs  the section's attributes
 * @param {Node[]} head  what stands above the form
 * @param {() => Promise<any>} read  the request
 * @param {(data: any, reload: () => Promise<unknown>) => HTMLElement} draw
 * @returns {HTMLElement}
 */
export function loadingSection(attrs, head, read, draw) {
  const body = h("div", null, h("p", { class: "muted" }, t("app.loading")));
  const box = h("section", attrs, ...head, body);
  const load = () =>
    read()
      .then((data) => body.replaceChildren(draw(data, load)))
      .catch((err) => body.replaceChildren(h("p", { class: "error", role: "alert" }, err.message)));
  void load();
  return box;
}

/**
 * A declared setting's label and help in the page's language (the server's words if none).
 * @param {any} s  the server's declaration
 * @returns {{label: string, help: string}}
 */
function settingTexts(s) {
  const [labelKey, helpKey] = TEXTS[/** @type {keyof typeof TEXTS} */ (s.name)] ?? [null, null];
  return { label: labelKey ? t(labelKey) : s.name, help: helpKey ? t(helpKey) : s.help };
}

/**
 * A declared number setting's label, checked range and input, as both forms draw it.
 * @param {any} s  the server's declaration (name, minimum, maximum, value, nullable, help)
 * @param {string} id  the input's id (its hint is ``${id}-hint``)
 * @param {string} unit
 * @param {Record<string, unknown>} [attrs]  more attributes of the input
 * @returns {{label: string, spec: any, el: HTMLInputElement, hints: string[]}}
 */
export function numberField(s, id, unit, attrs = {}) {
  const { label, help } = settingTexts(s);
  const spec = { label, min: s.minimum, max: s.maximum, unit };
  const el = /** @type {HTMLInputElement} */ (
    h("input", {
      id,
      name: s.name,
      value: s.value === null || s.value === undefined ? "" : formatDecimal(s.value),
      inputmode: "decimal",
      autocomplete: "off",
      "aria-describedby": `${id}-hint`,
      ...attrs,
    })
  );
  const hints = [help, t("settings.range", { range: rangeText(spec) })];
  if (s.nullable) hints.push(t("settings.emptyAllowed"));
  return { label, spec, el, hints };
}

/**
 * A number field's value as the server takes it (empty: null where allowed), or
 * undefined after marking the field and saying why in ``message``.
 * @param {HTMLInputElement | HTMLSelectElement} el
 * @param {any} setting  the server's declaration
 * @param {any} spec  the field's label and range
 * @param {HTMLElement} message
 * @returns {number | null | undefined}
 */
export function readNumber(el, setting, spec, message) {
  el.removeAttribute("aria-invalid");
  if (el.value.trim() === "" && setting.nullable) return null;
  const r = checkNumber(el.value, spec);
  if (r.ok) return r.value;
  el.setAttribute("aria-invalid", "true");
  setText(message, r.error);
  el.focus();
  return undefined;
}

/**
 * @param {string} rigId
 * @param {any} data  the server's answer
 * @param {() => Promise<unknown>} reload
 */
function settingsForm(rigId, data, reload) {
  const message = h("p", { class: "error", role: "alert", id: `settings-${rigId}-error` });
  /** @type {Map<string, {el: HTMLInputElement | HTMLSelectElement, setting: any, spec: any}>} */
  const fields = new Map();
  const rows = [];
  for (const s of data.settings) {
    const id = `settings-${rigId}-${s.name}`;
    const declared = s.unit === "s" ? "s" : s.unit === "input" ? data.inputUnit : s.unit === "output" ? data.outputUnit : "";
    const unit = unitSymbol(declared); // as a person reads it: a kit's "degC" is °C
    const { label, help } = settingTexts(s);
    const field =
      s.type === "choice"
        ? {
            spec: { label },
            el: h("select", { id, name: s.name }, s.choices.map((c) => h("option", { value: c, selected: c === s.value }, c in CHOICES ? t(CHOICES[c]) : c))),
            hints: [help],
          }
        : numberField(s, id, unit);
    const { spec, el, hints } = field;
    hints.push(t(APPLIES[s.applies] ?? "settings.appliesNow"));
    fields.set(s.name, { el, setting: s, spec });
    rows.push(h("div", { class: "field" }, h("label", { for: id }, label), el, h("span", { class: "hint", id: `${id}-hint` }, hints.join(" "))));
  }
  const save = h("button", { type: "submit", class: "primary" }, t("settings.save"));
  const form = h(
    "form",
    { novalidate: true, "aria-describedby": message.id, "data-version": String(data.version) },
    ...rows,
    message,
    save,
    h("p", { class: "muted" }, data.updatedBy ? t("settings.savedBy", { user: data.updatedBy }) : t("settings.fromFile")),
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(message, "");
    /** @type {Record<string, number | string | null>} */
    const values = {};
    for (const [name, { el, setting, spec }] of fields) {
      const value = setting.type === "choice" ? el.value : readNumber(el, setting, spec, message);
      if (value === undefined) return;
      if (value !== setting.value) values[name] = value;
    }
    save.disabled = true;
    try {
      await api.saveRigSettings(rigId, { version: data.version, values });
      announce(t("settings.saved", { rig: rigId }));
      await reload();
    } catch (err) {
      const where = err?.body?.errors?.[0]?.loc?.[2];
      const field = typeof where === "string" ? fields.get(where) : undefined;
      if (field) {
        field.el.setAttribute("aria-invalid", "true");
        setText(message, t("check.outOfRange", { label: field.spec.label, range: rangeText(field.spec), value: field.el.value }));
      } else setText(message, err.message);
      if (err?.body?.code === "settings_changed") await reload();
    } finally {
      save.disabled = false;
    }
  });
  return form;
}
