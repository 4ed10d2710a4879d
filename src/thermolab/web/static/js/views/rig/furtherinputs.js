// @ts-check
// The rig's further inputs that a run records (a kit's heater 2, Q2): a field
// each, within the range the rig declares, and a button that sets it (PUT
// /api/rigs/{rig}/channels/{name}: on the idle rig, or into the run, at its
// next sample). Only the controller sets them: for everyone else the card is
// locked, as the panels are. A twin's fan, which only a closed loop records,
// is set in the closed-loop panel (closedloop.js), as a disturbance.
// Each field follows the rig's level (a run's or a turn's end puts heater 2
// back at 0), except while the user is editing it: focused and changed since.
// The heater a closed loop drives (a kit's Q2, chosen in the closed-loop panel)
// is its PID's while the run goes: its field is disabled and says so.

import { api } from "../../api.js";
import { channelLabel } from "../../channelwords.js";
import { h, setText } from "../../dom.js";
import { formatDecimal, t } from "../../i18n.js";
import { unitSymbol } from "../../quantities.js";
import { checkNumber, rangeText } from "../../validate.js";

/** @typedef {{name: string, unit: string, min: number, max: number, default: number, level: number | null, recorded: boolean}} Actuator */
/**
 * A field's state: `edited` since the rig's level was last shown in it, and the
 * level `sent` that the rig's readings have not shown yet (null: none).
 * @typedef {{input: HTMLInputElement, error: HTMLElement, edited: boolean, sent: number | null, button: HTMLButtonElement, note: HTMLElement}} LevelField
 */

/**
 * The further input a run's closed loop drives (its `settings.control.heater`), or null.
 * @param {any} run
 * @returns {string | null}
 */
export function loopHeaterOf(run) {
  const heater = run?.settings?.control?.heater;
  return typeof heater === "string" && heater !== "u" ? heater : null;
}

/**
 * The levels of a rig's actuators by name, as `FurtherInputs.follow` takes them.
 * @param {{name: string, level: number | null}[]} actuators
 * @returns {Record<string, number | null>}
 */
export function levelsOf(actuators) {
  return Object.fromEntries(actuators.map((a) => [a.name, a.level]));
}

export class FurtherInputs {
  /**
   * @param {HTMLElement} parent
   * @param {string} rigId
   * @param {(name: string, applied: number | null) => void} onSet  a level the lab took (applied: null when it reached no device)
   */
  constructor(parent, rigId, onSet) {
    this.rigId = rigId;
    this.onSet = onSet;
    this.locked = true;
    /** @type {HTMLButtonElement[]} */
    this.buttons = [];
    /** @type {Map<string, LevelField>} */
    this.fields = new Map();
    this.fieldset = h("fieldset", { disabled: true });
    this.el = h(
      "section",
      { class: "card further-inputs", "aria-labelledby": "further-inputs-heading", hidden: true, "data-testid": "further-inputs" },
      h("h2", { id: "further-inputs-heading" }, t("furtherInputs.heading")),
      this.fieldset,
    );
    parent.append(this.el);
  }

  /**
   * The rig's actuators (readRig's): a field for each a run records, built once.
   * @param {Actuator[]} actuators
   */
  setActuators(actuators) {
    if (this.buttons.length) return;
    for (const a of actuators.filter((c) => c.recorded)) this.fieldset.append(this._field(a));
    this.el.hidden = this.buttons.length === 0;
  }

  /** @param {Actuator} a */
  _field(a) {
    const id = `channel-${a.name}`;
    const label = channelLabel(a.name, a.unit);
    const spec = { label, min: a.min, max: a.max, unit: unitSymbol(a.unit) };
    const input = h("input", { id, name: a.name, type: "text", inputmode: "decimal", value: formatDecimal(a.level ?? a.default), "aria-describedby": `${id}-range` });
    const error = h("span", { class: "field-error", role: "alert", "data-testid": `${id}-error` });
    const done = h("span", { class: "hint", role: "status", "data-testid": `${id}-status` });
    const note = h("span", { class: "hint", "data-testid": `${id}-driven` });
    const button = h("button", { type: "submit", "data-action": "set-channel", "data-channel": a.name }, t("furtherInputs.set"));
    this.buttons.push(button);
    /** @type {LevelField} */
    const field = { input, error, edited: false, sent: null, button, note };
    this.fields.set(a.name, field);
    input.addEventListener("input", () => {
      field.edited = true;
    });
    // A form of its own: Enter in the field sets the level, as the button does.
    const form = h(
      "form",
      { class: "field", novalidate: true },
      h("label", { for: id }, label),
      h("div", { class: "field inline" }, input, button),
      h("small", { id: `${id}-range` }, rangeText(spec)),
      error,
      done,
      note,
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      void this._set(a, spec, input, error, done);
    });
    return form;
  }

  /**
   * Check the level typed and send it; say in words what went wrong.
   * @param {Actuator} a
   * @param {import("../../validate.js").FieldSpec} spec
   * @param {HTMLInputElement} input
   * @param {HTMLElement} error
   * @param {HTMLElement} done
   */
  async _set(a, spec, input, error, done) {
    if (this.locked) return;
    setText(done, "");
    const checked = checkNumber(input.value, spec);
    if (!checked.ok) {
      input.setAttribute("aria-invalid", "true");
      setText(error, checked.error);
      input.focus();
      return;
    }
    input.removeAttribute("aria-invalid");
    setText(error, "");
    try {
      const answer = await api.setChannel(this.rigId, a.name, checked.value);
      const applied = typeof answer?.applied === "number" ? answer.applied : null;
      // Off, the rig takes it when powered: the record has it already.
      setText(done, applied === null ? t("furtherInputs.recorded") : "");
      const field = this.fields.get(a.name);
      if (field) Object.assign(field, { edited: false, sent: checked.value });
      this.onSet(a.name, applied);
    } catch (err) {
      setText(error, err instanceof Error ? err.message : String(err));
    }
  }

  /**
   * The input a closed loop drives now (null: none): its field is the PID's, disabled.
   * @param {string | null} name
   */
  setDriven(name) {
    for (const [channel, field] of this.fields) {
      const driven = channel === name;
      field.input.disabled = driven;
      field.button.disabled = driven;
      setText(field.note, driven ? t("furtherInputs.driven") : "");
    }
  }

  /** Locked for all but the controller (and while the lab cannot be reached). */
  setLocked(locked) {
    this.locked = locked;
    this.fieldset.disabled = locked;
    // A level sent before the turn ended may never show: the rig's readings rule again.
    if (locked) for (const field of this.fields.values()) field.sent = null;
  }

  /**
   * Show the rig's levels in the fields, but not in one the user is editing
   * (focused and changed since). A level just sent reaches the rig at a run's
   * next sample, so readings before it are skipped until one shows it, unless
   * `settled` (the rig's own account of its inputs, read after a run's end).
   * @param {Record<string, number | null | undefined>} levels  by channel name
   * @param {boolean} [settled]
   */
  follow(levels, settled = false) {
    for (const [name, field] of this.fields) {
      const level = levels[name];
      if (typeof level !== "number" || !Number.isFinite(level)) continue;
      if (field.sent !== null && !settled && level !== field.sent) continue;
      field.sent = null;
      if (field.edited && document.activeElement === field.input) continue;
      field.edited = false;
      const shown = formatDecimal(level);
      if (field.input.value === shown) continue;
      field.input.value = shown;
      field.input.removeAttribute("aria-invalid"); // a refused value typed earlier is gone
      setText(field.error, "");
    }
  }
}
