// @ts-check
// The "Now" card: the latest reading of the rig, in the units it publishes:
// its input u and output y, then every further input and output it declares
// (a kit's heater 2 and sensor 2, a twin's fan), each in its own unit.

import { channelLabel } from "../../channelwords.js";
import { h, setText } from "../../dom.js";
import { formatTime, t } from "../../i18n.js";
import { formatQuantity, quantityOfUnit, unitSymbol } from "../../quantities.js";

/** The rows every rig has, which no further channel's value overwrites. */
const OWN_ROWS = ["u", "y", "t", "k"];

export class Readout {
  /** @param {HTMLElement} parent */
  constructor(parent) {
    /** @type {Record<string, HTMLElement>} */
    this.value = {};
    /** @type {Record<string, HTMLElement>} */
    this.label = {};
    /** @type {Record<string, import("../../quantities.js").Quantity>} how each row's number is written, by its unit */
    this.quantity = { u: "volts", y: "volts" };
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
    setText(this.label.u, t("readout.inputUnit", { unit: unitSymbol(inputUnit) }));
    setText(this.label.y, t("readout.outputUnit", { unit: unitSymbol(outputUnit) }));
    this.quantity.u = quantityOfUnit(inputUnit);
    this.quantity.y = quantityOfUnit(outputUnit);
  }

  /**
   * The rig's further channels as the rig declares them: a row each, added the
   * first time, after the sample's (inputs first, then outputs). An input shows
   * its level now (at its default once handed over); an output shows "–" until
   * a reading brings it.
   * @param {{name: string, unit: string, level: number | null}[]} inputs
   * @param {{name: string, unit: string}[]} [outputs]
   */
  setFurther(inputs, outputs = []) {
    let last = this.value.k;
    for (const c of [...inputs, ...outputs]) {
      if (OWN_ROWS.includes(c.name)) continue;
      if (!this.value[c.name]) {
        this.value[c.name] = h("dd", { "data-readout": c.name, "data-unit": unitSymbol(c.unit) }, "–");
        this.label[c.name] = h("dt", null, channelLabel(c.name, c.unit));
        this.quantity[c.name] = quantityOfUnit(c.unit);
        last.after(this.label[c.name], this.value[c.name]);
      }
      last = this.value[c.name];
    }
    for (const c of inputs) this.setLevel(c.name, c.level);
  }

  /**
   * A further channel's value now (a level the controller has just set).
   * @param {string} name
   * @param {number | null} level
   */
  setLevel(name, level) {
    if (this.label[name] && !OWN_ROWS.includes(name)) setText(this.value[name], formatQuantity(level, this.quantity[name]));
  }

  /** @param {{u: number, y: number, t: number, k?: number, run?: number | null, channels?: Record<string, number | null>}} s  a live sample */
  update(s) {
    // A run's samples and the idle readings carry the further channels by name
    // (a kit's t2 and q2; a closed loop's run records the fan).
    for (const [name, level] of Object.entries(s.channels ?? {})) this.setLevel(name, level);
    setText(this.value.u, formatQuantity(s.u, this.quantity.u));
    setText(this.value.y, formatQuantity(s.y, this.quantity.y));
    // A run's time is seconds since START; an idle reading's is the time of day,
    // and its label says so.
    const idle = s.run === null || s.run === undefined;
    setText(this.label.t, t(idle ? "readout.clock" : "readout.time"));
    setText(this.value.t, idle ? formatTime(new Date(s.t * 1000)) : formatQuantity(s.t, "seconds"));
    setText(this.value.k, s.k ?? "–");
  }
}
