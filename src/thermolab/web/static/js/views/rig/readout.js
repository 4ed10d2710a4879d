// @ts-check
// The "Now" card: the latest reading of the rig, in the units it publishes.

import { h, setText } from "../../dom.js";
import { formatTime, t } from "../../i18n.js";
import { formatQuantity } from "../../quantities.js";

/** @type {Record<string, string>} The words for each actuator a rig's kind declares, by its name. */
const ACTUATOR_NAMES = { fan: "readout.actuator.fan", q2: "readout.actuator.q2" };

export class Readout {
  /** @param {HTMLElement} parent */
  constructor(parent) {
    /** @type {Record<string, HTMLElement>} */
    this.value = {};
    /** @type {Record<string, HTMLElement>} */
    this.label = {};
    const dl = h("dl", { class: "facts readout" });
    for (const [key, label] of [["u", t("readout.input")], ["y", t("readout.output")], ["t", t("readout.time")], ["k", t("readout.sample")]]) {
      this.value[key] = h("dd", { "data-readout": key }, "–");
      this.label[key] = h("dt", null, label);
      dl.append(this.label[key], this.value[key]);
    }
    parent.append(h("section", { class: "card", "aria-labelledby": "now-heading" }, h("h2", { id: "now-heading" }, t("readout.heading")), dl));
  }

  /** Units as the rig publishes them (volts for the paper's box, % and °C for a TCLab). */
  setUnits(inputUnit, outputUnit) {
    setText(this.label.u, t("readout.inputUnit", { unit: inputUnit }));
    setText(this.label.y, t("readout.outputUnit", { unit: outputUnit }));
  }

  /**
   * The rig's further actuators (a twin's fan), as the rig says them: a row each,
   * added the first time, with the level now (at its default once handed over).
   * @param {{name: string, unit: string, level: number | null}[]} actuators
   */
  setActuators(actuators) {
    for (const a of actuators) {
      if (!this.value[a.name]) {
        this.value[a.name] = h("dd", { "data-readout": a.name }, "–");
        const name = a.name in ACTUATOR_NAMES ? t(ACTUATOR_NAMES[a.name]) : a.name;
        this.label[a.name] = h("dt", null, t("readout.actuatorUnit", { name, unit: a.unit }));
        this.value.k.after(this.label[a.name], this.value[a.name]);
      }
      setText(this.value[a.name], formatQuantity(a.level, "volts"));
    }
  }

  /** @param {{u: number, y: number, t: number, k?: number, run?: number | null, channels?: Record<string, number | null>}} s  a live sample */
  update(s) {
    for (const [name, level] of Object.entries(s.channels ?? {})) {
      // A closed loop's run records its actuators (the fan) with every sample.
      if (this.label[name] && !["u", "y", "t", "k"].includes(name)) setText(this.value[name], formatQuantity(level, "volts"));
    }
    setText(this.value.u, formatQuantity(s.u, "volts"));
    setText(this.value.y, formatQuantity(s.y, "volts"));
    // A run's time is seconds since START; an idle reading's is the time of day,
    // and its label says so.
    const idle = s.run === null || s.run === undefined;
    setText(this.label.t, t(idle ? "readout.clock" : "readout.time"));
    setText(this.value.t, idle ? formatTime(new Date(s.t * 1000)) : formatQuantity(s.t, "seconds"));
    setText(this.value.k, s.k ?? "–");
  }
}
