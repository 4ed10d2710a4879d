// The rig page: live image, live charts (with the identified model laid over
// the data), the current estimates, the convergence of the recursive methods,
// the access panel and the paper's three panels. Everything live comes over
// one WebSocket (LiveClient); commands go over HTTP.

import { api } from "../api.js";
import { Chart } from "../charts.js";
import { announce, h, setText } from "../dom.js";
import { LiveClient } from "../live.js";
import { fmt, predict, predictionBase } from "../model.js";
import { DecimatingBuffer, RingBuffer } from "../ring.js";
import { buildRunSpec, methodName, methodTitle, panelOfRun, readEstimate, readRun, RECURSIVE } from "../runspec.js";
import { enumValues, hasProperty, numericRange, openapi } from "../schema.js";
import { readAccess, readRig, stateLabel } from "../shapes.js";
import { parseCsv } from "../csv.js";
import { AccessPanel } from "./access.js";
import { Panels } from "./panels.js";

/** Samples shown by the live charts (the issue's 2000-sample window). */
export const WINDOW = 2000;
/** Points kept per convergence trajectory (decimated beyond). */
const TRAJECTORY_POINTS = 4000;
const CAMERA_MS = 1000;
/** Reading the rig over HTTP while the live socket is down. */
const POLL_MS = 3000;

export function mount(main, { params }, ctx) {
  const rigId = params[0];
  ctx.setTitle(`Rig ${rigId}`);
  const page = new RigPage(main, rigId, ctx);
  return () => page.destroy();
}

class RigPage {
  constructor(main, rigId, ctx) {
    this.rigId = rigId;
    this.ctx = ctx;
    this.rig = null;
    this.run = null; // current or last run (readRun)
    this.ring = new RingBuffer(WINDOW, ["t", "u", "y"]);
    this.yhat = new Float64Array(WINDOW);
    // What the charts show: the samples of one run, or idle readings (run null).
    this.segment = { run: null, y0: Number.NaN, t0: Number.NaN, firstK: Number.NaN, lastK: -1, loading: false, pending: [] };
    this.trajectories = new Map(); // method -> {buf, kChart, tChart}
    this.overlayMethod = null;
    this._uiFrame = 0;
    this._destroyed = false;
    this._build(main);
    this.client = new LiveClient(rigId, {
      onMessage: (msg) => this._onMessage(msg),
      onStatus: (s) => this._onStatus(s),
    });
    this._online = () => this.client.reconnectNow();
    window.addEventListener("online", this._online);
    this.client.start();
    this._startCamera();
    void this._poll();
  }

  /**
   * Read the rig over HTTP: at once (limits and access before the socket's
   * hello), then every few seconds while the live socket is not open, so the
   * page stays current and the user's place stays alive (any request for the
   * rig counts as presence) through a socket outage.
   */
  async _poll() {
    if (this._destroyed) return;
    if (this.client.state !== "open" || !this.rig) {
      try {
        const rig = readRig(await api.rig(this.rigId));
        if (this._destroyed) return;
        if (this.client.state !== "open" || !this.rig) {
          this._setRig(rig);
          this.access.update(rig.access);
        }
        if (this.client.state !== "open" && this.run?.status === "running") await this._pollRun();
      } catch (err) {
        if (err.status === 404) {
          this._error(err.message);
          return;
        }
      }
    }
    this._pollTimer = setTimeout(() => void this._poll(), POLL_MS);
  }

  // -- layout ---------------------------------------------------------------------------

  _build(main) {
    this.badge = h("span", { class: "badge", "data-testid": "rig-state" }, "…");
    this.stateDetail = h("span", { class: "muted" });
    this.banner = h("p", { class: "error", role: "alert", "data-testid": "rig-error" });
    main.append(
      h("p", { class: "crumbs" }, h("a", { href: "#/" }, "Rigs"), " › ", this.rigId),
      h("h1", null, h("span", { "data-testid": "rig-title" }, this.rigId), " ", this.badge),
      h("p", null, this.stateDetail),
      this.banner,
    );
    const grid = h("div", { class: "rig-grid" });
    main.append(grid);
    const side = h("div", { class: "rig-side" });
    const charts = h("section", { class: "card live-charts", "aria-labelledby": "charts-heading" });
    grid.append(side, charts);

    // Live image.
    this.camera = h("img", { class: "camera", alt: `Live image of rig ${this.rigId}`, width: "320", height: "240", hidden: true });
    this.cameraNote = h("p", { class: "muted small" }, "No image yet.");
    side.append(
      h(
        "section",
        { class: "card", "aria-labelledby": "camera-heading" },
        h("h2", { id: "camera-heading" }, "Live image"),
        h("div", { class: "camera-box" }, this.camera, this.cameraNote),
      ),
    );

    // Access.
    this.access = new AccessPanel(side, this.rigId, {
      onError: (m) => this._error(m),
      onChange: () => this._updateLock(),
      // The control routes answer with the rig as the caller now sees it.
      onAnswer: (answer) => {
        if (answer && typeof answer === "object" && answer.access) {
          const rig = readRig(answer);
          this._setState(rig.state, rig.detail);
          this.access.update(rig.access);
        }
      },
    });

    // Readouts.
    this.readout = {};
    const dl = h("dl", { class: "facts readout" });
    this.readoutLabel = {};
    for (const [key, label] of [["u", "Input u"], ["y", "Output y"], ["t", "Time t"], ["k", "Sample k"]]) {
      this.readout[key] = h("dd", { "data-readout": key }, "–");
      this.readoutLabel[key] = h("dt", null, label);
      dl.append(this.readoutLabel[key], this.readout[key]);
    }
    side.append(h("section", { class: "card", "aria-labelledby": "now-heading" }, h("h2", { id: "now-heading" }, "Now"), dl));

    // Charts.
    this.chartNote = h("p", { class: "muted small", "data-testid": "chart-note" });
    this.overlaySelect = h("select", { id: "overlay-method" });
    this.overlaySelect.addEventListener("change", () => {
      this.overlayMethod = this.overlaySelect.value || null;
      this.outChart.invalidate();
    });
    this.liveButton = h("button", { type: "button", class: "link-button", hidden: true }, "Show live readings");
    this.liveButton.addEventListener("click", () => this._startSegment(null));
    charts.append(
      h("h2", { id: "charts-heading" }, "Live charts"),
      this.chartNote,
      h("div", { class: "field inline" }, h("label", { for: "overlay-method" }, "Model drawn over the output"), this.overlaySelect),
      this.liveButton,
    );
    this.outChart = new Chart(charts, {
      label: "Output y and model prediction against time",
      description: "The measured output and, once a model is identified, its prediction. The current values are listed under Now.",
      xLabel: "t (s)",
      yLabel: "output y",
      series: [{ label: "output y" }, { label: "model", dash: [6, 4], color: "#D55E00", width: 2, auto: false }],
      source: () => this._outputData(),
    });
    this.inChart = new Chart(charts, {
      label: "Input u against time",
      xLabel: "t (s)",
      yLabel: "input u",
      height: 160,
      series: [{ label: "input u", color: "#009E73" }],
      source: () => [this.ring.column("t"), this.ring.column("u")],
    });

    // The three panels (rebuilt once the rig's limits are known).
    this.panelsHost = h("div", { class: "panels-host" });
    main.append(this.panelsHost);
    this.panelActions = {
      start: (panel, values, automatic) => this._start(panel, values, automatic),
      setpoint: (u) => api.setInput(this.rigId, u),
      end: () => api.stopRun(this.rigId),
    };
    this.panels = new Panels(this.panelsHost, this._limits(null, null), this.panelActions);

    // Convergence of the recursive methods.
    this.convergence = h("section", { class: "card convergence", "aria-labelledby": "conv-heading" });
    this.convergenceEmpty = h("p", { class: "muted" }, "The moving-window and weighted methods draw Ks(k) and Ts(k) here while they run.");
    this.convergence.append(h("h2", { id: "conv-heading" }, "Convergence of Ks and Ts"), this.convergenceEmpty);
    main.append(this.convergence);
  }

  /**
   * What the panels may accept: the rig's published input range, and the run
   * settings' ranges from the server's own schema (RunIn in /openapi.json).
   */
  _limits(rig, doc) {
    const ranges = {};
    for (const [field, prop] of [["dt", "dt"], ["samples", "samples"], ["window", "window"], ["block", "block"], ["gamma", "gamma"], ["pmax", "pmax"]]) {
      const r = doc ? numericRange(doc, "RunIn", prop) : null;
      if (r) ranges[field] = r;
    }
    return {
      inputMin: rig ? rig.inputMin : -10,
      inputMax: rig ? rig.inputMax : 10,
      inputUnit: rig?.inputUnit ?? "V",
      ranges,
      w0: Boolean(doc && hasProperty(doc, "RunIn", "w0")),
      offsets: doc ? enumValues(doc, "RunIn", "offset") : null,
    };
  }

  /** Without the socket, follow one's own run over HTTP (progress, estimates, its end). */
  async _pollRun() {
    const id = this.run.id;
    let run;
    try {
      run = readRun(await api.run(id));
    } catch {
      return; // someone else's run (403): only the socket shows it
    }
    if (this._destroyed || !this.run || this.run.id !== id) return;
    for (const [m, est] of run.estimates) {
      if (!this.run.estimates.has(m) || est.final || est.k > (this.run.estimates.get(m).k ?? -1)) this.run.estimates.set(m, est);
    }
    run.estimates = this.run.estimates;
    const ended = run.status !== "running";
    this.run = run;
    this.panels.setRun(run);
    this._updateOverlayChoices();
    this._invalidateCharts();
    if (ended) {
      announce(`Run ${run.id} ended${run.endReason ? `: ${run.endReason}` : ""}.`);
      // The samples never came live: draw the whole run, with its model, from the store.
      this._startSegment(run.id, true);
    }
    this._noteSegment();
  }

  // -- live messages --------------------------------------------------------------------

  _onStatus(s) {
    const conn = document.getElementById("conn");
    if (s.state === "open") {
      if (conn.textContent) setText(conn, "Connected again.");
      setTimeout(() => {
        if (this.client.state === "open") setText(conn, "");
      }, 2000);
    } else if (s.state === "waiting") {
      setText(conn, `Live updates interrupted; reconnecting in ${Math.ceil(s.delayMs / 1000)} s (the page is refreshed every few seconds meanwhile).`);
    } else if (s.state === "closed" && s.code) {
      setText(conn, "");
      if (s.code === 4404) this._error(`There is no rig called ${this.rigId}.`);
    }
  }

  _onMessage(msg) {
    if (msg.history) {
      // What the server held from before we came: only the current run's samples
      // and estimates matter (the hello already said what the state is).
      const current = this.run?.status === "running" ? this.run.id : null;
      if ((msg.type !== "sample" && msg.type !== "estimate") || current === null || msg.run !== current) return;
    }
    switch (msg.type) {
      case "hello":
        this._setRig(readRig(msg.rig));
        this.access.update(readAccess(msg.access));
        this._setRun(readRun(msg.run), true);
        break;
      case "sample":
        this._sample(msg);
        break;
      case "estimate":
        this._estimate(msg);
        break;
      case "run":
        this._runEvent(msg);
        break;
      case "access":
        this.access.update(readAccess(msg.access));
        break;
      case "state":
        this._setState(msg.state, msg.detail);
        break;
      case "error":
        this._error(msg.detail ?? "The server refused a message.");
        break;
      default:
        break; // unknown types are for newer clients
    }
  }

  _setRig(rig) {
    const first = this.rig === null;
    this.rig = rig;
    setText(this.root("rig-title"), rig.title || rig.id);
    if (first) {
      // Units as the rig publishes them (volts for the paper's box, % and °C for a TCLab).
      setText(this.readoutLabel.u, `Input u (${rig.inputUnit})`);
      setText(this.readoutLabel.y, `Output y (${rig.outputUnit})`);
      // The panels' ranges come from the rig and the server's schema; both are
      // known before the panels unlock (they are locked until access is known).
      void openapi().then((doc) => {
        if (this._destroyed) return;
        this.schemaDoc = doc;
        this._rebuildPanels(this._limits(rig, doc));
      });
    }
    this._setState(rig.state, rig.detail);
  }

  _rebuildPanels(limits) {
    const selected = this.panels.selected;
    this.panelsHost.replaceChildren();
    const panels = new Panels(this.panelsHost, limits, this.panelActions);
    panels.select(selected, false);
    this.panels = panels;
    this._updateLock();
    if (this.run) panels.setRun(this.run);
  }

  root(testid) {
    return document.querySelector(`[data-testid="${testid}"]`);
  }

  _setState(state, detail) {
    const before = this.rig?.state;
    if (this.rig) this.rig.state = state;
    setText(this.badge, stateLabel(state));
    this.badge.dataset.state = state;
    setText(this.stateDetail, detail ?? "");
    this.access.setRigState(state);
    this._updateLock();
    if (before && before !== state && (state === "fault" || state === "out_of_service")) {
      announce(`Rig ${this.rigId}: ${stateLabel(state)}${detail ? `: ${detail}` : ""}.`, "alert");
    }
  }

  _updateLock() {
    const a = this.access.access;
    const state = this.rig?.state;
    let reason = "";
    if (!a) reason = "Connecting…";
    else if (state === "out_of_service") reason = "This rig is out of service.";
    else if (state === "fault") reason = "The rig reports a fault; the controls are locked.";
    else if (a.role !== "controller") {
      reason =
        a.role === "queued" || a.queuePosition
          ? `You are number ${a.queuePosition} in the queue; the controls unlock when your turn comes.`
          : "You are watching: the controls are read-only. Ask for control to use them.";
    }
    this.panels.setLocked(Boolean(reason), reason);
  }

  _setRun(run, fromHello) {
    if (run && this.run && this.run.id === run.id) {
      // The same run again (a reconnection): keep what came live.
      for (const [m, est] of this.run.estimates) if (!run.estimates.has(m)) run.estimates.set(m, est);
    }
    this.run = run;
    this.panels.setRun(run);
    this._updateOverlayChoices();
    if (run && run.status === "running") {
      if (this.segment.run !== run.id) this._startSegment(run.id, false);
      this.panels.selectById(panelOfRun(run));
      if (fromHello && !this._askedHistory) {
        // Joined half-way through a run: ask the server for all it holds (the
        // run's samples from the store, the recent estimates) once.
        this._askedHistory = true;
        this.client.replayAll();
      }
    }
    this._noteSegment();
  }

  _runEvent(msg) {
    const run = readRun(msg.run);
    if (!run) return;
    if (msg.event === "started") {
      this._clearTrajectories();
      this.run = run;
      this._startSegment(run.id, false);
      this.panels.setRun(run);
      this.panels.selectById(panelOfRun(run));
      announce(`Run ${run.id} started.`);
    } else {
      // The run object brings the final status and each method's final estimate;
      // keep what came live for any method it does not mention.
      if (this.run && this.run.id === run.id) {
        for (const [m, est] of this.run.estimates) if (!run.estimates.has(m)) run.estimates.set(m, est);
      }
      this.run = run;
      this.panels.setRun(run);
      announce(`Run ${run.id} ended${run.endReason ? `: ${run.endReason}` : ""}.`);
    }
    this._updateOverlayChoices();
    this._noteSegment();
  }

  /** Start showing a new segment (a run, or idle readings). */
  _startSegment(runId, loadHistory) {
    this.ring.clear();
    this.segment = { run: runId, y0: Number.NaN, t0: Number.NaN, firstK: Number.NaN, lastK: -1, loading: false, pending: [] };
    if (runId !== null && loadHistory) void this._loadHistory(runId);
    this._noteSegment();
    this._invalidateCharts();
  }

  _noteSegment() {
    const seg = this.segment;
    let text;
    if (seg.run === null) text = "Live readings of the rig (no run is being shown).";
    else if (this.run && this.run.id === seg.run && this.run.status !== "running") {
      text = `Run ${seg.run} (${this.run.status}); the live readings continue under Now.`;
    } else text = `Run ${seg.run}, live.`;
    if (seg.loading) text += " Loading the earlier samples…";
    setText(this.chartNote, text);
    this.liveButton.hidden = seg.run === null || (this.run?.id === seg.run && this.run.status === "running");
  }

  /** Fill the window with the samples a watcher joining mid-run missed. */
  async _loadHistory(runId) {
    const seg = this.segment;
    seg.loading = true;
    this._noteSegment();
    try {
      const res = await fetch(api.csvUrl(runId), { credentials: "same-origin" });
      if (!res.ok) throw new Error(`${res.status}`);
      const table = parseCsv(await res.text(), ["k", "t", "u", "y"]);
      if (this._destroyed || this.segment !== seg) return;
      const n = table.k.length;
      if (n > 0) seg.y0 = table.k[0] === 0 ? table.y[0] : Number.NaN;
      for (let i = Math.max(0, n - WINDOW); i < n; i += 1) {
        this._pushSample({ k: table.k[i], t: table.t[i], u: table.u[i], y: table.y[i] });
      }
    } catch {
      // The window then starts with the live samples; nothing else is lost.
    } finally {
      if (this.segment === seg) {
        seg.loading = false;
        for (const s of seg.pending) this._pushSample(s);
        seg.pending = [];
        this._noteSegment();
        this._invalidateCharts();
      }
    }
  }

  _sample(s) {
    this._updateReadout(s);
    const seg = this.segment;
    const runId = s.run ?? null;
    if (runId !== seg.run) {
      if (runId === null) return; // idle readings while a run is on show: numbers only
      this._startSegment(runId, false);
    }
    if (this.segment.loading) {
      if (this.segment.pending.length < WINDOW) this.segment.pending.push(s);
      return;
    }
    this._pushSample(s);
    if (runId !== null && this.run?.id === runId) this.panels.progress(s.k);
  }

  _pushSample(s) {
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
    const t = seg.run === null ? s.t - seg.t0 : s.t;
    const lastT = this.ring.last("t");
    if (this.ring.length && !(t > lastT)) this.ring.clear(); // a new time base
    this.ring.push({ t, u: s.u, y: s.y });
    this._invalidateCharts();
  }

  _updateReadout(s) {
    setText(this.readout.u, fmt(s.u, 4));
    setText(this.readout.y, fmt(s.y, 5));
    // A run's time is seconds since START; an idle reading's is the time of day.
    setText(this.readout.t, s.run === null || s.run === undefined ? new Date(s.t * 1000).toLocaleTimeString() : fmt(s.t, 6));
    setText(this.readout.k, s.k ?? "–");
  }

  _estimate(e) {
    if (!this.run || e.run !== this.run.id) return;
    const method = e.method;
    const est = readEstimate(e);
    this.run.estimates.set(method, est);
    const base = methodName({ method }).split(/[:#]/)[0];
    if (RECURSIVE.has(base) && !est.final) {
      const t = this._trajectory(method);
      // Only estimates with a first-order meaning are drawn (uPlot has no NaN gaps).
      if (est.valid && Number.isFinite(est.K) && Number.isFinite(est.tau)) t.buf.push({ k: e.k, K: est.K, tau: est.tau });
    }
    if (!this.overlaySelect.querySelector(`option[value="${CSS.escape(method)}"]`)) this._updateOverlayChoices();
    this._scheduleUi();
  }

  _scheduleUi() {
    if (this._uiFrame) return;
    this._uiFrame = requestAnimationFrame(() => {
      this._uiFrame = 0;
      this.panels.estimatesChanged();
      for (const t of this.trajectories.values()) {
        t.kChart.invalidate();
        t.tChart.invalidate();
      }
      this.outChart.invalidate();
    });
  }

  _trajectory(method) {
    let t = this.trajectories.get(method);
    if (t) return t;
    this.convergenceEmpty.hidden = true;
    const buf = new DecimatingBuffer(TRAJECTORY_POINTS, ["k", "K", "tau"]);
    const box = h("div", { class: "conv-pair" }, h("h3", null, methodTitle(method)));
    this.convergence.append(box);
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

  _clearTrajectories() {
    for (const t of this.trajectories.values()) {
      t.kChart.destroy();
      t.tChart.destroy();
      t.box.remove();
    }
    this.trajectories.clear();
    this.convergenceEmpty.hidden = false;
  }

  _updateOverlayChoices() {
    const methods = this.run ? this.run.methods.map(methodName) : [];
    for (const m of this.run?.estimates?.keys() ?? []) if (!methods.includes(m)) methods.push(m);
    const current = this.overlaySelect.value;
    this.overlaySelect.replaceChildren(
      h("option", { value: "" }, "none"),
      ...methods.map((m) => h("option", { value: m }, methodTitle(m))),
    );
    const keep = methods.includes(current) ? current : (methods[methods.length > 1 && methods[0] === "srm" ? 1 : 0] ?? "");
    this.overlaySelect.value = keep;
    this.overlayMethod = keep || null;
  }

  _overlayModel() {
    if (!this.run || this.segment.run !== this.run.id || !this.overlayMethod) return null;
    const est = this.run.estimates.get(this.overlayMethod);
    if (!est || !est.valid || !(est.K > -Infinity) || !(est.tau > 0)) return null;
    return est;
  }

  _outputData() {
    const t = this.ring.column("t");
    const u = this.ring.column("u");
    const y = this.ring.column("y");
    const model = this._overlayModel();
    if (!model || y.length === 0) {
      this.yhat.fill(Number.NaN);
      return [t, y, this.yhat.subarray(0, y.length)];
    }
    const seg = this.segment;
    const fromStart = seg.firstK === 0 && this.ring.length === seg.lastK + 1;
    const y0 = Number.isFinite(seg.y0) ? seg.y0 : y[0];
    // A warm rig's run fits its operating point: the model settles there, not at y0.
    const base = predictionBase(this.run.operatingPoint?.used, model.W, y0);
    const yhat = predict(u, base, model, this.run.dt, this.yhat, (fromStart ? y0 : y[0]) - base);
    return [t, y, yhat];
  }

  _invalidateCharts() {
    this.outChart.invalidate();
    this.inChart.invalidate();
  }

  // -- commands -------------------------------------------------------------------------

  async _start(panel, values, automatic) {
    const spec = buildRunSpec(panel, values, automatic, {
      w0: hasProperty(this.schemaDoc, "RunIn", "w0"),
      offset: hasProperty(this.schemaDoc, "RunIn", "offset"),
    });
    const answer = await api.startRun(this.rigId, spec);
    const run = readRun(answer);
    if (run && (!this.run || this.run.id !== run.id)) {
      this._clearTrajectories();
      this.run = run;
      this._startSegment(run.id, false);
      this.panels.setRun(run);
      this._updateOverlayChoices();
    }
  }

  _error(message) {
    setText(this.banner, message);
    clearTimeout(this._bannerTimer);
    this._bannerTimer = setTimeout(() => setText(this.banner, ""), 15000);
  }

  // -- camera ---------------------------------------------------------------------------

  _startCamera() {
    let lastUrl = null;
    const next = () => {
      this._cameraTimer = setTimeout(load, CAMERA_MS);
    };
    const load = async () => {
      if (this._destroyed) return;
      if (document.hidden) return next();
      try {
        const res = await fetch(api.cameraUrl(this.rigId), { cache: "no-store", credentials: "same-origin" });
        if (!res.ok) throw new Error(`${res.status}`);
        const blob = await res.blob();
        if (this._destroyed) return;
        const url = URL.createObjectURL(blob);
        this.camera.src = url;
        this.camera.hidden = false;
        // Object URLs hold their image until revoked: keep exactly one alive.
        if (lastUrl) URL.revokeObjectURL(lastUrl);
        lastUrl = url;
        setText(this.cameraNote, "");
      } catch {
        this.camera.hidden = true;
        setText(this.cameraNote, "No image at the moment.");
      }
      next();
    };
    this._revokeCamera = () => {
      if (lastUrl) URL.revokeObjectURL(lastUrl);
    };
    void load();
  }

  destroy() {
    this._destroyed = true;
    this.client.stop();
    window.removeEventListener("online", this._online);
    clearTimeout(this._cameraTimer);
    clearTimeout(this._pollTimer);
    clearTimeout(this._bannerTimer);
    this._revokeCamera?.();
    if (this._uiFrame) cancelAnimationFrame(this._uiFrame);
    this.access.destroy();
    this.outChart.destroy();
    this.inChart.destroy();
    this._clearTrajectories();
    const conn = document.getElementById("conn");
    if (conn) setText(conn, "");
  }
}
