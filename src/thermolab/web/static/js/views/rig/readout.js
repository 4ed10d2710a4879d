// @ts-check
// The "Now" card: the latest reading of the rig, in the units it publishes.

import { h, setText } from "../../dom.js";
import { fmt } from "../../model.js";
import { formatTime, t } from "../../i18n.js";

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

  /** @param {{u: number, y: number, t: number, k?: number, run?: number | null}} s  a live sample */
  update(s) {
    setText(this.value.u, fmt(s.u, 4));
    setText(this.value.y, fmt(s.y, 5));
    // A run's time is seconds since START; an idle reading's is the time of day.
    setText(this.value.t, s.run === null || s.run === undefined ? formatTime(new Date(s.t * 1000)) : fmt(s.t, 6));
    setText(this.value.k, s.k ?? "–");
  }
}
