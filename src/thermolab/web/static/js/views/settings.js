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
  const body = h("div", null, h("p", { class: "muted" }, t("app.loading")));
  const box = h(
    "section",
    { class: "rig-settings", "aria-labelledby": hid, "data-settings": rigId },
    h("h3", { id: hid }, t("settings.heading")),
    h("p", { class: "muted" }, t("settings.when")),
    body,
  );
  const load = () =>
    api
      .rigSettings(rigId)
      .then((data) => body.replaceChildren(settingsForm(rigId, data, load)))
      .catch((err) => body.replaceChildren(h("p", { class: "error", role: "alert" }, err.message)));
  void load();
  return box;
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
    const [labelKey, helpKey] = TEXTS[s.name] ?? [null, null];
    const label = labelKey ? t(labelKey) : s.name;
    const unit = s.unit === "s" ? "s" : s.unit === "input" ? data.inputUnit : s.unit === "output" ? data.outputUnit : "";
    const spec = { label, min: s.minimum, max: s.maximum, unit };
    let el;
    const hints = [helpKey ? t(helpKey) : s.help];
    if (s.type === "choice") {
      el = h("select", { id, name: s.name }, s.choices.map((c) => h("option", { value: c, selected: c === s.value }, c in CHOICES ? t(CHOICES[c]) : c)));
    } else {
      el = h("input", { id, name: s.name, value: s.value === null ? "" : formatDecimal(s.value), inputmode: "decimal", autocomplete: "off", "aria-describedby": `${id}-hint` });
      hints.push(t("settings.range", { range: rangeText(spec) }));
      if (s.nullable) hints.push(t("settings.emptyAllowed"));
    }
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
      el.removeAttribute("aria-invalid");
      let value;
      if (setting.type === "choice") value = el.value;
      else if (el.value.trim() === "" && setting.nullable) value = null;
      else {
        const r = checkNumber(el.value, spec);
        if (!r.ok) {
          el.setAttribute("aria-invalid", "true");
          setText(message, r.error);
          el.focus();
          return;
        }
        value = r.value;
      }
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
