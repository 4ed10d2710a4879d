// @ts-check
// Convergence of the recursive methods: Ks(k) and Ts(k) charts per method,
// each trajectory kept in bounded memory (decimated beyond TRAJECTORY_POINTS).

import { Chart } from "../../charts.js";
import { h } from "../../dom.js";
import { DecimatingBuffer } from "../../ring.js";
import { methodTitle } from "../../runspec.js";
import { t } from "../../i18n.js";

/** Points kept per convergence trajectory (decimated beyond). */
const TRAJECTORY_POINTS = 4000;

export class Convergence {
  /** @param {HTMLElement} parent */
  constructor(parent) {
    /** method -> its buffer, charts and box */
    this.trajectories = new Map();
    this.el = h("section", { class: "card convergence", "aria-labelledby": "conv-heading" });
    this.empty = h("p", { class: "muted" }, t("convergence.empty"));
    this.el.append(h("h2", { id: "conv-heading" }, t("convergence.heading")), this.empty);
    parent.append(this.el);
  }

  /** One point of a method's trajectory. */
  push(method, k, K, tau) {
    this._trajectory(method).buf.push({ k, K, tau });
  }

  invalidate() {
    for (const traj of this.trajectories.values()) {
      traj.kChart.invalidate();
      traj.tChart.invalidate();
    }
  }

  _trajectory(method) {
    let traj = this.trajectories.get(method);
    if (traj) return traj;
    this.empty.hidden = true;
    const buf = new DecimatingBuffer(TRAJECTORY_POINTS, ["k", "K", "tau"]);
    const box = h("div", { class: "conv-pair" }, h("h3", null, methodTitle(method)));
    this.el.append(box);
    const kChart = new Chart(box, {
      label: t("convergence.kChart", { method: methodTitle(method) }),
      xLabel: t("axis.sample"),
      yLabel: t("axis.K"),
      height: 180,
      series: [{ label: t("series.K"), color: "#0072B2" }],
      source: () => [buf.column("k"), buf.column("K")],
    });
    const tChart = new Chart(box, {
      label: t("convergence.tauChart", { method: methodTitle(method) }),
      xLabel: t("axis.sample"),
      yLabel: t("axis.tau"),
      height: 180,
      series: [{ label: t("series.tau"), color: "#CC79A7" }],
      source: () => [buf.column("k"), buf.column("tau")],
    });
    traj = { buf, kChart, tChart, box };
    this.trajectories.set(method, traj);
    return traj;
  }

  clear() {
    for (const traj of this.trajectories.values()) {
      traj.kChart.destroy();
      traj.tChart.destroy();
      traj.box.remove();
    }
    this.trajectories.clear();
    this.empty.hidden = false;
  }
}
