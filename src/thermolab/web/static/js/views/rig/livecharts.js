// @ts-check
// The live charts: output (with the identified model laid over it) and input
// against time, over a bounded window of the segment on show — one run's
// samples, or the rig's idle readings. A watcher who joins mid-run gets the
// run's earlier samples from its CSV; when the server's replay of a long run
// skips its middle (a `truncated` notice), the card says so and links the CSV.
// A rig with further channels a run records (a kit's sensor 2 and heater 2)
// gets each as a labelled trace of its own, on the chart of its unit: t2
// beside y, q2 beside u.

import { api } from "../../api.js";
import { channelName } from "../../channelwords.js";
import { COLORS, Chart, TIME_WINDOWS } from "../../charts.js";
import { parseCsv } from "../../csv.js";
import { h, setText } from "../../dom.js";
import { predict, predictionBase } from "../../model.js";
import { RingBuffer } from "../../ring.js";
import { methodName, methodTitle, runPair, runStatusText } from "../../runspec.js";
import { t } from "../../i18n.js";

/** Samples shown by the live charts (the 2000-sample window). */
export const WINDOW = 2000;

/**
 * What the charts show: the samples of one run, or idle readings (run null).
 * @typedef {object} Segment
 * @property {number | null} run
 * @property {number} y0  the run's first output (NaN: not known)
 * @property {number} t0  the first idle reading's time (idle time is drawn from it)
 * @property {number} firstK  the first sample index shown
 * @property {number} lastK  the newest sample index shown
 * @property {boolean} loading  the run's earlier samples are being fetched
 * @property {Sample[]} pending  live samples held while they load
 */
/** @typedef {{t: number, u: number, y: number, k?: number, run?: number | null, channels?: Record<string, number | null>}} Sample */

/** The colours of further traces (Okabe–Ito, apart from y's, the model's and u's). */
const FURTHER_COLORS = [COLORS[3], COLORS[4], COLORS[5]];

/**
 * A segment with nothing in it yet.
 * @param {number | null} run  the run whose samples it holds (null: idle readings)
 * @returns {Segment}
 */
function emptySegment(run) {
  return { run, y0: Number.NaN, t0: Number.NaN, firstK: Number.NaN, lastK: -1, loading: false, pending: [] };
}

export class LiveCharts {
  /**
   * @param {HTMLElement} parent
   * @param {() => any} getRun  the page's current (or last) run, as runspec.readRun gives it
   */
  constructor(parent, getRun) {
    this.getRun = getRun;
    /** The further channels drawn (setFurther): outputs beside y, inputs beside u. */
    this.further = { outputs: /** @type {string[]} */ ([]), inputs: /** @type {string[]} */ ([]) };
    this.ring = new RingBuffer(WINDOW, ["t", "u", "y"]);
    this.yhat = new Float64Array(WINDOW);
    this.segment = emptySegment(null);
    this.overlayMethod = null;
    this._destroyed = false;
    const card = h("section", { class: "card live-charts", "aria-labelledby": "charts-heading" });
    this.card = card;
    parent.append(card);
    this.note = h("p", { class: "muted small", "data-testid": "chart-note" });
    this.truncatedNote = h("p", { class: "notice small", role: "status", hidden: true, "data-testid": "chart-truncated" });
    this.overlaySelect = h("select", { id: "overlay-method" });
    this.overlaySelect.addEventListener("change", () => {
      this.overlayMethod = this.overlaySelect.value || null;
      this.outChart.invalidate();
    });
    this.liveButton = h("button", { type: "button", class: "link-button", hidden: true }, t("charts.showLive"));
    this.liveButton.addEventListener("click", () => this.startSegment(null, false));
    card.append(
      h("h2", { id: "charts-heading" }, t("charts.heading")),
      this.note,
      this.truncatedNote,
      h("div", { class: "field inline" }, h("label", { for: "overlay-method" }, t("charts.overlay")), this.overlaySelect),
      this.liveButton,
    );
    const charts = this._buildCharts();
    this.outChart = charts.output;
    this.inChart = charts.input;
  }

  /** The output and input charts, with a trace for each further channel drawn. */
  _buildCharts() {
    const trace = (name, i) => ({ label: channelName(name), color: FURTHER_COLORS[i % FURTHER_COLORS.length] });
    const { outputs, inputs } = this.further;
    const output = new Chart(this.card, {
      label: t("charts.output"),
      description: t("charts.outputDescription"),
      xLabel: t("axis.time"),
      yLabel: t("axis.output"),
      series: [
        { label: t("axis.output") },
        { label: t("series.model"), dash: [6, 4], color: "#D55E00", width: 2, auto: false },
        ...outputs.map(trace),
      ],
      source: () => this._outputData(),
      // One choice for both charts: the input chart shows the same time as the output.
      windows: TIME_WINDOWS,
      onWindow: (seconds) => this.inChart.setWindow(seconds),
    });
    const input = new Chart(this.card, {
      label: t("charts.input"),
      xLabel: t("axis.time"),
      yLabel: t("axis.input"),
      height: 160,
      series: [{ label: t("axis.input"), color: "#009E73" }, ...inputs.map((name, i) => trace(name, i + outputs.length))],
      source: () => [this.ring.column("t"), this.ring.column("u"), ...inputs.map((name) => this.ring.column(name))],
    });
    return { output, input };
  }

  /**
   * Draw the rig's further channels that a run records, each on the chart of
   * its unit: its further outputs beside y (a kit's t2 in °C), its recorded
   * further inputs beside u (q2 in %). A twin's fan, which only a closed loop
   * records, stays off. A rig with none keeps its charts as they are; one with
   * some gets them rebuilt once, when the page first learns the rig (before its
   * first sample: the segment on show is loaded again, if any).
   * @param {{inputUnit: string, outputUnit: string, outputs: {name: string, unit: string}[],
   *   actuators: {name: string, unit: string, recorded: boolean}[]}} rig  as readRig gives it
   */
  setFurther(rig) {
    const own = ["t", "u", "y"];
    const outputs = rig.outputs.filter((o) => o.unit === rig.outputUnit && !own.includes(o.name)).map((o) => o.name);
    const inputs = rig.actuators.filter((a) => a.recorded && a.unit === rig.inputUnit && !own.includes(a.name)).map((a) => a.name);
    if (outputs.length + inputs.length === 0) return;
    this.further = { outputs, inputs };
    this.ring = new RingBuffer(WINDOW, [...own, ...outputs, ...inputs]);
    this.outChart.destroy();
    this.inChart.destroy();
    const charts = this._buildCharts();
    this.outChart = charts.output;
    this.inChart = charts.input;
    this.startSegment(this.segment.run, this.segment.run !== null);
  }

  /** Start showing a new segment (a run, or idle readings). */
  startSegment(runId, loadHistory) {
    this.ring.clear();
    this.segment = emptySegment(runId);
    this.truncatedNote.hidden = true;
    this.truncatedNote.replaceChildren();
    if (runId !== null && loadHistory) void this._loadHistory(runId);
    this.noteSegment();
    this.invalidate();
  }

  /** Say what the charts show. */
  noteSegment() {
    const seg = this.segment;
    const run = this.getRun();
    let text;
    if (seg.run === null) text = t("charts.idle");
    else if (run && run.id === seg.run && run.status !== "running") {
      text = t("charts.runEnded", { run: seg.run, status: runStatusText(run.status) });
    } else text = t("charts.runLive", { run: seg.run });
    if (seg.loading) text = t("charts.loading", { note: text });
    setText(this.note, text);
    this.liveButton.hidden = seg.run === null || (run?.id === seg.run && run.status === "running");
  }

  /**
   * The server's `truncated` notice (docs/live-protocol.md, "Replay"): the run
   * on show was too long to replay whole, so only its newest samples came. Say
   * that the charts show the run's last part, and offer its whole record.
   * @param {{run: number, from: number, limit: number}} msg
   */
  truncated(msg) {
    if (msg.run !== this.segment.run) return;
    const csv = h(
      "a",
      { href: api.csvUrl(msg.run), download: `run-${msg.run}.csv`, "data-testid": "chart-truncated-csv" },
      t("charts.truncatedCsv"),
    );
    this.truncatedNote.replaceChildren(t("charts.truncated", { run: msg.run, from: msg.from, limit: msg.limit }), " ", csv);
    this.truncatedNote.hidden = false;
  }

  /** Fill the window with the samples a watcher joining mid-run missed. */
  async _loadHistory(runId) {
    const seg = this.segment;
    seg.loading = true;
    this.noteSegment();
    try {
      const res = await fetch(api.csvUrl(runId), { credentials: "same-origin" });
      if (!res.ok) throw new Error(`${res.status}`);
      const text = await res.text();
      const table = parseCsv(text, ["k", "t", "u", "y"]);
      const names = [...this.further.outputs, ...this.further.inputs];
      /** @type {Record<string, Float64Array>} */
      const further = {};
      for (const name of names) {
        try {
          Object.assign(further, parseCsv(text, [name]));
        } catch {
          // A record without the channel: its trace starts with the live samples.
        }
      }
      if (this._destroyed || this.segment !== seg) return;
      const n = table.k.length;
      if (n > 0) seg.y0 = table.k[0] === 0 ? table.y[0] : Number.NaN;
      for (let i = Math.max(0, n - WINDOW); i < n; i += 1) {
        const channels = names.length ? Object.fromEntries(names.map((name) => [name, further[name]?.[i] ?? null])) : undefined;
        this._push({ k: table.k[i], t: table.t[i], u: table.u[i], y: table.y[i], channels });
      }
    } catch {
      // The window then starts with the live samples; nothing else is lost.
    } finally {
      if (this.segment === seg) {
        seg.loading = false;
        for (const s of seg.pending) this._push(s);
        seg.pending = [];
        this.noteSegment();
        this.invalidate();
      }
    }
  }

  /**
   * A live sample. Returns whether it was drawn as part of a run (idle
   * readings while a run is on show, and samples held while the history
   * loads, are not).
   */
  sample(s) {
    const runId = s.run ?? null;
    if (runId !== this.segment.run) {
      if (runId === null) return false; // idle readings while a run is on show: numbers only
      this.startSegment(runId, false);
    }
    if (this.segment.loading) {
      if (this.segment.pending.length < WINDOW) this.segment.pending.push(s);
      return false;
    }
    this._push(s);
    return runId !== null;
  }

  _push(s) {
    const seg = this.segment;
    if (typeof s.k === "number") {
      if (s.k <= seg.lastK) return; // already have it (history and live overlap)
      seg.lastK = s.k;
      if (Number.isNaN(seg.firstK)) seg.firstK = s.k;
      if (s.k === 0) seg.y0 = s.y;
    }
    // Idle readings carry wall-clock time (epoch seconds): draw them from the
    // first one shown, like a run's time from its START.
    if (seg.run === null && !Number.isFinite(seg.t0)) seg.t0 = s.t;
    const time = seg.run === null ? s.t - seg.t0 : s.t;
    const lastT = this.ring.last("t");
    if (this.ring.length && !(time > lastT)) this.ring.clear(); // a new time base
    /** @type {Record<string, number | null | undefined>} */
    const row = { t: time, u: s.u, y: s.y };
    // A sample without the channel (from the store, of a run that did not record it): a gap.
    for (const name of this.further.outputs) row[name] = s.channels?.[name];
    for (const name of this.further.inputs) row[name] = s.channels?.[name];
    this.ring.push(row);
    this.invalidate();
  }

  /** Whether the model select already offers `method`. */
  offers(method) {
    return Boolean(this.overlaySelect.querySelector(`option[value="${CSS.escape(method)}"]`));
  }

  /** Offer the current run's methods as the model drawn over the output. */
  updateOverlayChoices() {
    const run = this.getRun();
    const methods = run ? run.methods.map(methodName) : [];
    for (const m of run?.estimates?.keys() ?? []) if (!methods.includes(m)) methods.push(m);
    const current = this.overlaySelect.value;
    this.overlaySelect.replaceChildren(
      h("option", { value: "" }, t("charts.noModel")),
      ...methods.map((m) => h("option", { value: m }, methodTitle(m))),
    );
    const keep = methods.includes(current) ? current : (methods[methods.length > 1 && methods[0] === "srm" ? 1 : 0] ?? "");
    this.overlaySelect.value = keep;
    this.overlayMethod = keep || null;
  }

  _overlayModel() {
    const run = this.getRun();
    if (!run || this.segment.run !== run.id || !this.overlayMethod) return null;
    const est = run.estimates.get(this.overlayMethod);
    if (!est || !est.valid || !(est.K > -Infinity) || !(est.tau > 0)) return null;
    return est;
  }

  _outputData() {
    const time = this.ring.column("t");
    const y = this.ring.column("y");
    const model = this._overlayModel();
    // The model is of the run's pair (a kit's Q2 -> T2): driven by its input, from its output.
    const pair = runPair(this.getRun());
    const kept = ["u", "y", ...this.further.outputs, ...this.further.inputs];
    if (!model || y.length === 0 || !kept.includes(pair.input) || !kept.includes(pair.output)) {
      this.yhat.fill(Number.NaN);
      return [time, y, this.yhat.subarray(0, y.length), ...this._furtherOutputs()];
    }
    const run = this.getRun();
    const u = this.ring.column(pair.input);
    const out = pair.output === "y" ? y : this.ring.column(pair.output);
    const seg = this.segment;
    const fromStart = seg.firstK === 0 && this.ring.length === seg.lastK + 1;
    const y0 = pair.output === "y" && Number.isFinite(seg.y0) ? seg.y0 : out[0];
    // A warm rig's run fits its operating point: the model settles there, not at y0.
    const base = predictionBase(run.operatingPoint?.used, model.W, y0);
    const yhat = predict(u, base, model, run.dt, this.yhat, (fromStart ? y0 : out[0]) - base);
    return [time, y, yhat, ...this._furtherOutputs()];
  }

  /** The further outputs' columns, in the output chart's order. */
  _furtherOutputs() {
    return this.further.outputs.map((name) => this.ring.column(name));
  }

  /** Redraw the model only (a new estimate). */
  invalidateModel() {
    this.outChart.invalidate();
  }

  invalidate() {
    this.outChart.invalidate();
    this.inChart.invalidate();
  }

  destroy() {
    this._destroyed = true;
    this.outChart.destroy();
    this.inChart.destroy();
  }
}
