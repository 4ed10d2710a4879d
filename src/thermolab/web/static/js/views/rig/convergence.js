// Convergence of the recursive methods: Ks(k) and Ts(k) charts per method,
// each trajectory kept in bounded memory (decimated beyond TRAJECTORY_POINTS).

import { Chart } from "../../charts.js";
import { h } from "../../dom.js";
import { DecimatingBuffer } from "../../ring.js";
import { methodTitle } from "../../runspec.js";

/** Points kept per convergence trajectory (decimated beyond). */
const TRAJECTORY_POINTS = 4000;

export class Convergence {
  /** @param {HTMLElement} parent */
  constructor(parent) {
    /** method -> its buffer, charts and box */
    this.trajectories = new Map();
    this.el = h("section", { class: "card convergence", "aria-labelledby": "conv-heading" });
    this.empty = h("p", { class: "muted" }, "The moving-window and weighted methods draw Ks(k) and Ts(k) here while they run.");
    this.el.append(h("h2", { id: "conv-heading" }, "Convergence of Ks and Ts"), this.empty);
    parent.append(this.el);
  }

  /** One point of a method's trajectory. */
  push(method, k, K, tau) {
    this._trajectory(method).buf.push({ k, K, tau });
  }

  invalidate() {
    for (const t of this.trajectories.values()) {
      t.kChart.invalidate();
      t.tChart.invalidate();
    }
  }

  _trajectory(method) {
    let t = this.trajectories.get(method);
    if (t) return t;
    this.empty.hidden = true;
    const buf = new DecimatingBuffer(TRAJECTORY_POINTS, ["k", "K", "tau"]);
    const box = h("div", { class: "conv-pair" }, h("h3", null, methodTitle(method)));
    this.el.append(box);
    const kChart = new Chart(box, {
      label: `Ks against sample, ${methodTitle(method)}`,
      xLabel: "sample k",
      yLabel: "Ks",
      height: 180,
      series: [{ label: "Ks(k)", color: "#0072B2" }],
      source: () => [buf.column("k"), buf.column("K")],
    });
    const tChart = new Chart(box, {
      label: `Ts against sample, ${methodTitle(method)}`,
      xLabel: "sample k",
      yLabel: "Ts (s)",
      height: 180,
      series: [{ label: "Ts(k)", color: "#CC79A7" }],
      source: () => [buf.column("k"), buf.column("tau")],
    });
    t = { buf, kChart, tChart, box };
    this.trajectories.set(method, t);
    return t;
  }

  clear() {
    for (const t of this.trajectories.values()) {
      t.kChart.destroy();
      t.tChart.destroy();
      t.box.remove();
    }
    this.trajectories.clear();
    this.empty.hidden = false;
  }
}
