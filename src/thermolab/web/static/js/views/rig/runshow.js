// @ts-check
// The run on show on the rig page: the current (or last) run, followed through
// its start, samples, estimates and end, from the live socket or (while it is
// down) over HTTP; it feeds the live charts, the convergence charts and the
// panels, and says starts and ends aloud.

import { announce } from "../../dom.js";
import { hasTrajectory } from "../../methods.js";
import { panelOfRun, readEstimate, readRun } from "../../runspec.js";
import { endReasonText } from "../../runwords.js";
import { Convergence } from "./convergence.js";
import { LiveCharts } from "./livecharts.js";
import { t } from "../../i18n.js";

export class RunShow {
  /**
   * @param {HTMLElement} chartsParent  where the live charts go
   * @param {HTMLElement} convergenceParent  where the convergence charts go
   * @param {() => any} getPanels  the page's current Panels (they are rebuilt once)
   */
  constructor(chartsParent, convergenceParent, getPanels) {
    this.getPanels = getPanels;
    /** The current or last run (runspec.readRun), or null. */
    this.run = null;
    this._uiFrame = 0;
    this.charts = new LiveCharts(chartsParent, () => this.run);
    this.convergence = new Convergence(convergenceParent);
  }

  /** Keep what came live for any method the new copy of the same run does not mention. */
  _keepLiveEstimates(run) {
    if (run && this.run && this.run.id === run.id) {
      for (const [m, est] of this.run.estimates) if (!run.estimates.has(m)) run.estimates.set(m, est);
    }
  }

  /** The run of a hello message; returns whether it is running (the caller may ask for its history). */
  set(run) {
    this._keepLiveEstimates(run); // the same run again (a reconnection)
    this.run = run;
    this.getPanels().setRun(run);
    this.charts.updateOverlayChoices();
    const running = Boolean(run && run.status === "running");
    if (running) {
      if (this.charts.segment.run !== run.id) this.charts.startSegment(run.id, false);
      this.getPanels().selectById(panelOfRun(run));
    }
    this.charts.noteSegment();
    return running;
  }

  /** A `run` message of the live protocol (started, or ended). */
  event(msg) {
    const run = readRun(msg.run);
    if (!run) return;
    if (msg.event === "started") {
      this.started(run);
      this.getPanels().selectById(panelOfRun(run));
      announce(t("run.started", { run: run.id }));
    } else {
      // The run object brings the final status and each method's final estimate.
      this._keepLiveEstimates(run);
      this.run = run;
      this.getPanels().setRun(run);
      this._announceEnd(run);
    }
    this.charts.updateOverlayChoices();
    this.charts.noteSegment();
  }

  /** A run that has just started (here or by the live protocol): fresh charts for it. */
  started(run) {
    this.convergence.clear();
    this.run = run;
    this.charts.startSegment(run.id, false);
    this.getPanels().setRun(run);
  }

  _announceEnd(run) {
    const why = endReasonText(run.endReason);
    const reason = why ? [why.text, why.detail].filter(Boolean).join(": ") : "";
    announce(reason ? t("run.endedWhy", { run: run.id, reason }) : t("run.ended", { run: run.id }));
  }

  /** A live sample: drawn, and the panel's progress moved on when it is the run's. */
  sample(msg) {
    if (this.charts.sample(msg) && this.run?.id === msg.run) this.getPanels().progress(msg.k);
  }

  /** A live `estimate` message. */
  estimate(e) {
    if (!this.run || e.run !== this.run.id) return;
    const method = e.method;
    const est = readEstimate(e);
    this.run.estimates.set(method, est);
    // Only estimates with a first-order meaning are drawn (uPlot has no NaN gaps).
    if (hasTrajectory(method) && !est.final && est.valid && Number.isFinite(est.K) && Number.isFinite(est.tau)) {
      this.convergence.push(method, e.k, est.K, est.tau);
    }
    if (!this.charts.offers(method)) this.charts.updateOverlayChoices();
    this._scheduleUi();
  }

  /** Redraw what estimates change, once per frame however many arrive. */
  _scheduleUi() {
    if (this._uiFrame) return;
    this._uiFrame = requestAnimationFrame(() => {
      this._uiFrame = 0;
      this.getPanels().estimatesChanged();
      this.convergence.invalidate();
      this.charts.invalidateModel();
    });
  }

  /** The run as read over HTTP while the socket is down (progress, estimates, its end). */
  polled(run) {
    if (!this.run || this.run.id !== run.id) return;
    for (const [m, est] of run.estimates) {
      if (!this.run.estimates.has(m) || est.final || est.k > (this.run.estimates.get(m).k ?? -1)) this.run.estimates.set(m, est);
    }
    run.estimates = this.run.estimates;
    const ended = run.status !== "running";
    this.run = run;
    this.getPanels().setRun(run);
    this.charts.updateOverlayChoices();
    this.charts.invalidate();
    if (ended) {
      this._announceEnd(run);
      // The samples never came live: draw the whole run, with its model, from the store.
      this.charts.startSegment(run.id, true);
    }
    this.charts.noteSegment();
  }

  destroy() {
    if (this._uiFrame) cancelAnimationFrame(this._uiFrame);
    this.charts.destroy();
    this.convergence.clear();
  }
}
