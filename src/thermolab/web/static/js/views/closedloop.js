// @ts-check
// The fourth panel, "Closed loop": a PID on the rig's output (issue #11).
//
// Built from what the server declares: GET /api/control (every PID and tuning
// parameter with its range, the rules and their forms) and GET
// /api/rigs/{rig}/loop (units, output limit, the disturbance fan, the run's
// loop now). From a run's identified model, the tuning table (GET
// /api/runs/{id}/tuning) gives each rule's gains with the predicted step to the
// set point the student typed, or to the server's default for the rig's ranges
// (a step of the input from rest: the middle of the ±10 V box is no step);
// picking a row fills the gains. START posts a run with `control`; while it
// runs: set-point steps, manual/auto, the fan, END. The chart draws r, y, u and
// the prediction; in adaptive mode the gains' trajectories and why the tuner
// holds them. At the end the measured figures are shown beside the predicted.
// A rig with more than one heater and sensor pair (a kit: Q1/T1, Q2/T2) gets a
// chooser of the heater the PID drives; the other is a disturbance set by hand
// (heater 2 in the "Further inputs" card, heater 1 here while the loop drives 2).

import { api, request } from "../api.js";
import { channelName } from "../channelwords.js";
import { Chart, COLORS } from "../charts.js";
import { h, replaceChildren, setText, tParts } from "../dom.js";
import { formatNumber, t } from "../i18n.js";
import { loopNotes, loopWord } from "../loopwords.js";
import { unitSymbol } from "../quantities.js";
import { checkNumber, rangeText } from "../validate.js";
import { num, tuningTable } from "./loop/tuning.js";

const enc = encodeURIComponent;
/** Points kept for the chart (a closed-loop lesson is a few thousand samples). */
const KEEP = 4000;
/** How often the loop's state (mode, gains, why adaptive holds) is read while a run goes. */
const POLL_MS = 2000;

const loopApi = {
  control: () => request("GET", "/api/control"),
  loop: (rig) => request("GET", `/api/rigs/${enc(rig)}/loop`),
  tuning: (run, query) => request("GET", `/api/runs/${enc(run)}/tuning${query}`),
  mode: (rig, body) => request("PUT", `/api/rigs/${enc(rig)}/runs/current/mode`, body),
  setpoint: (rig, setpoint) => request("PUT", `/api/rigs/${enc(rig)}/runs/current/setpoint`, { setpoint }),
  gains: (rig, body) => request("PUT", `/api/rigs/${enc(rig)}/runs/current/gains`, body),
  fan: (rig, percent) => request("PUT", `/api/rigs/${enc(rig)}/runs/current/fan`, { percent }),
};

/** The run's own pair: its input u and output y (a kit's heater 1 and sensor 1). */
const OWN = "u";

/**
 * A heater and sensor pair in the reader's words.
 * @param {{heater: string, sensor: string}} pair
 */
function pairLabel(pair) {
  return pair.heater === OWN ? t("loop.pairOwn") : t("loop.pair", { heater: channelName(pair.heater), sensor: channelName(pair.sensor) });
}

/** The modes' labels (the server's words are "manual" and "auto"). */
const MODE_KEYS = { manual: "loop.modeManual", auto: "loop.modeAuto" };

/** A number as a field holds it: the page's decimal mark, six significant digits, no grouping. @param {number} v */
function plain(v) {
  return formatNumber(v, { maximumSignificantDigits: 6, useGrouping: false });
}

export class ClosedLoopPanel {
  /** @param {HTMLElement} parent @param {string} rigId */
  constructor(parent, rigId) {
    this.rigId = rigId;
    this.locked = true;
    this.runId = null;
    this.running = false;
    /** @type {any} */
    this.model = null;
    /** @type {Record<string, number[]>} */
    this.series = { t: [], r: [], y: [], u: [], p: [], kp: [], ti: [] };
    /** @type {Record<string, any>} */
    this.fields = {};
    // Built once the server's declarations are read (_build).
    /** @type {any} */ this.form = null;
    /** @type {any} */ this.startButton = null;
    /** @type {any} */ this.liveSet = null;
    /** @type {any} */ this.status = null;
    /** @type {any} */ this.hold = null;
    /** @type {any} */ this.figures = null;
    /** @type {any} */ this.error = null;
    /** @type {any} */ this.chart = null;
    /** @type {any} */ this.uChart = null;
    /** @type {any} */ this.gainChart = null;
    /** @type {any} */ this.gainHost = null;
    /** @type {any} */ this.predicted = null;
    /** @type {any} */ this.declared = null;
    /** @type {any} */ this.rig = null;
    /** @type {any} */ this.modeSelect = null;
    /** @type {any} */ this.adaptive = null;
    /** The heater chooser (a rig with more than one pair), and the pair of the run shown. */
    /** @type {any} */ this.pairSelect = null;
    /** @type {any} */ this.otherHost = null;
    /** @type {{heater: string, sensor: string}} */ this.runPair = { heater: OWN, sensor: "y" };
    /** The table shown, the run it came from and the row picked (its prediction follows the set point). */
    /** @type {any} */ this.tuning = null;
    /** @type {any} */ this.tuningRun = null;
    /** @type {string | null} */ this.usedRule = null;
    this.el = h("section", { class: "card closed-loop", "aria-labelledby": "loop-heading", "data-testid": "closed-loop" },
      h("h2", { id: "loop-heading" }, t("loop.heading")),
      h("p", {}, t("loop.lede")));
    this.body = h("div", {});
    this.el.append(this.body);
    parent.append(this.el);
    this._timer = 0;
    void this._load();
  }

  async _load() {
    try {
      const [declared, rig] = await Promise.all([loopApi.control(), loopApi.loop(this.rigId)]);
      this.declared = declared;
      this.rig = rig;
      this._build();
    } catch (err) {
      setText(this.body, err.message);
    }
  }

  /** The check of a declared parameter, as a field spec (its range and unit). */
  _spec(name, label, unit = "") {
    const p = this.declared.parameters.find((q) => q.name === name);
    const max = p.maximum ?? Infinity;
    return { label, min: p.magnitude ? -max : p.minimum ?? -Infinity, max, unit: unitSymbol(unit || p.unit), exclusiveMin: p.exclusiveMinimum };
  }

  _field(name, label, spec, value) {
    const id = `loop-${name}`;
    const input = h("input", { id, name, type: "text", inputmode: "decimal", value: value === undefined ? "" : String(value), "aria-describedby": `${id}-range` });
    const error = h("span", { class: "field-error", role: "alert" });
    this.fields[name] = { input, error, spec };
    return h("div", { class: "field" }, h("label", { for: id }, label), input,
      h("small", { id: `${id}-range` }, rangeText(spec)), error);
  }

  _read(names) {
    /** @type {Record<string, number>} */
    const values = {};
    let ok = true;
    for (const name of names) {
      const f = this.fields[name];
      const r = checkNumber(f.input.value, f.spec);
      setText(f.error, r.ok ? "" : r.error);
      if (r.ok) {
        f.input.removeAttribute("aria-invalid");
        values[name] = r.value;
      } else {
        f.input.setAttribute("aria-invalid", "true");
        if (ok) f.input.focus();
        ok = false;
      }
    }
    return ok ? values : null;
  }

  _build() {
    const rig = this.rig;
    // Units as a person reads them (a kit's "degC" is °C), in ranges, labels and axes.
    const out = unitSymbol(rig.outputUnit);
    const inUnit = unitSymbol(rig.inputUnit);
    const [uMin, uMax] = rig.inputRange;
    // Below the output limit; any value under it (the server refuses one at the step's start).
    const setpointSpec = { label: t("loop.setpoint"), min: -Infinity, max: rig.outputLimit ?? Infinity, exclusiveMax: true, unit: out };
    // A manual start holds the input the rig rests at, not the range's end (−10 V on the box).
    const rest = Number.isFinite(rig.safeInput) ? rig.safeInput : Math.min(Math.max(0, uMin), uMax);
    this.error = h("p", { class: "form-error", role: "alert", "data-testid": "loop-error" });
    if (!rig.closedLoop) {
      replaceChildren(this.body, h("p", {}, t("loop.noOutput")));
      return;
    }
    // Tuning table from a run's identified model.
    this.modelRun = this._field("modelRun", t("loop.modelRun"), { label: t("loop.modelRun"), min: 1, max: Infinity, integer: true });
    this.tableButton = h("button", { type: "button", "data-action": "tuning" }, t("loop.tuningTable"));
    this.tableButton.addEventListener("click", () => void this._tuningTable());
    this.table = h("div", { class: "table-wrap", "data-testid": "tuning-table" });
    // The controller.
    const modeSelect = h("select", { id: "loop-mode", name: "mode" },
      ...this.declared.modes.map((m) => h("option", { value: m }, t(MODE_KEYS[m]))));
    modeSelect.value = "auto"; // a set-point step from rest; manual starts open-loop
    this.modeSelect = modeSelect;
    this.adaptive = h("input", { id: "loop-adaptive", type: "checkbox", name: "adaptive" });
    // Which heater the PID drives: only where there is a choice (a one-heater rig looks as before).
    const pairs = Array.isArray(rig.pairs) ? rig.pairs : [];
    /** @type {any[]} */
    const chooser = [];
    if (pairs.length > 1) {
      this.pairSelect = h("select", { id: "loop-heater", name: "heater", "data-testid": "loop-heater" },
        ...pairs.map((p) => h("option", { value: p.heater, "data-sensor": p.sensor }, pairLabel(p))));
      this.pairSelect.addEventListener("change", () => this._pairChanged());
      chooser.push(h("div", { class: "field" }, h("label", { for: "loop-heater" }, t("loop.heater")), this.pairSelect),
        h("p", { class: "hint" }, t("loop.heaterHint")));
    }
    this.startButton = h("button", { type: "button", "data-action": "loop-start" }, t("loop.start"));
    this.startButton.addEventListener("click", () => void this._start());
    this.form = h("fieldset", {},
      h("legend", {}, t("loop.controller")),
      h("p", { class: "hint" }, t("loop.tuningHint")),
      h("div", { class: "fields" }, this.modelRun, this.tableButton), this.table,
      h("div", { class: "fields" },
        this._field("kp", t("loop.kp"), this._spec("kp", t("loop.kp"), `${inUnit}/${out}`)),
        this._field("ti", t("loop.ti"), this._spec("ti", t("loop.ti"))),
        this._field("td", t("loop.td"), this._spec("td", t("loop.td")), 0),
        this._field("setpoint", t("loop.setpoint"), setpointSpec),
        this._field("u", t("loop.manualInput"), { label: t("loop.manualInput"), min: uMin, max: uMax, unit: inUnit }, rest),
        this._field("dt", t("loop.dt"), { label: t("loop.dt"), min: 0.01, max: 3600, unit: "s" }, 1),
        this._field("samples", t("loop.samples"), { label: t("loop.samples"), min: 1, max: 200000, integer: true }, 1200)),
      ...chooser,
      h("div", { class: "field" }, h("label", { for: "loop-mode" }, t("loop.mode")), modeSelect),
      h("div", { class: "field" }, h("label", { for: "loop-adaptive" }, t("loop.adaptive")), this.adaptive),
      this.startButton);
    // Live commands.
    this.stepField = this._field("step", t("loop.newSetpoint"), { ...setpointSpec, label: t("loop.newSetpoint") });
    const button = (action, key, fn) => {
      const b = h("button", { type: "button", "data-action": action }, t(key));
      b.addEventListener("click", () => void this._send(fn));
      return b;
    };
    const live = [this.stepField,
      button("loop-step", "loop.step", () => {
        const v = this._read(["step"]);
        return v && loopApi.setpoint(this.rigId, v.step);
      }),
      button("loop-auto", "loop.toAuto", () => loopApi.mode(this.rigId, { mode: "auto" })),
      button("loop-manual", "loop.toManual", () => loopApi.mode(this.rigId, { mode: "manual" })),
      button("loop-end", "loop.end", () => api.stopRun(this.rigId))];
    if (this.pairSelect) {
      // While the PID drives another heater, the run's own input (heater 1) is the disturbance.
      this.otherHost = h("div", { class: "fields", hidden: true },
        this._field("other", t("loop.otherHeater"), { label: t("loop.otherHeater"), min: uMin, max: uMax, unit: inUnit }, rest),
        button("loop-other", "loop.otherSet", () => {
          const v = this._read(["other"]);
          return v && api.setInput(this.rigId, v.other);
        }));
      live.push(this.otherHost);
    }
    if (rig.fan) {
      live.push(this._field("fan", t("loop.fan"), { label: t("loop.fan"), min: rig.fan.minimum, max: rig.fan.maximum, unit: unitSymbol(rig.fan.unit) }, 50),
        button("loop-fan", "loop.fanSet", () => {
          const v = this._read(["fan"]);
          return v && loopApi.fan(this.rigId, v.fan);
        }));
    }
    this.liveSet = h("fieldset", {}, h("legend", {}, t("loop.live")), h("div", { class: "fields" }, ...live));
    this.status = h("p", { role: "status", "data-testid": "loop-status" });
    this.hold = h("p", { "data-testid": "loop-hold" });
    this.figures = h("div", { class: "table-wrap", "data-testid": "loop-figures" });
    this.chartHost = h("div", {});
    this.chart = new Chart(this.chartHost, {
      label: t("loop.chart"), xLabel: t("loop.time"), yLabel: t("axis.withUnit", { axis: t("loop.outputAxis"), unit: out }),
      series: [{ label: "r", color: COLORS[6], dash: [6, 4] }, { label: "y", color: COLORS[0] },
        { label: t("loop.predicted"), color: COLORS[1], dash: [2, 3], auto: false }],
      source: () => [this.series.t, this.series.r, this.series.y, this.series.p],
    });
    this.uChart = new Chart(this.chartHost, {
      label: t("loop.inputChart"), xLabel: t("loop.time"), yLabel: t("axis.withUnit", { axis: t("axis.input"), unit: inUnit }),
      series: [{ label: "u", color: COLORS[2] }], source: () => [this.series.t, this.series.u], height: 140,
    });
    this.gainHost = h("div", { hidden: true });
    this.gainChart = new Chart(this.gainHost, {
      label: t("loop.gainsChart"), xLabel: t("loop.time"), yLabel: t("loop.gainsAxis"),
      series: [{ label: t("loop.kp"), color: COLORS[3] }, { label: t("loop.ti"), color: COLORS[4] }],
      source: () => [this.series.t, this.series.kp, this.series.ti], height: 140,
    });
    replaceChildren(this.body, this.form, this.liveSet, this.error, this.status, this.hold, this.chartHost, this.gainHost, this.figures);
    this._render();
  }

  async _send(fn) {
    setText(this.error, "");
    try {
      await fn();
    } catch (err) {
      setText(this.error, err.message);
    }
  }

  /** The set point typed for the table: undefined (the server's default) or a checked value; null: refused. */
  _tuningSetpoint() {
    const f = this.fields.setpoint;
    if (f.input.value.trim() === "") return undefined;
    const v = this._read(["setpoint"]);
    return v ? v.setpoint : null;
  }

  async _tuningTable(runId) {
    const v = runId ? { modelRun: runId } : this._read(["modelRun"]);
    if (!v) return;
    const setpoint = this._tuningSetpoint();
    if (setpoint === null) return;
    setText(this.error, "");
    try {
      // For the loop's pair only: the server refuses a model of another (a Q2 -> T2 model, Q1/T1).
      const answer = await loopApi.tuning(v.modelRun, this._query(setpoint));
      this.tuningRun = v.modelRun;
      this.usedRule = null;
      this.predicted = null;
      this._showTable(answer.table);
    } catch (err) {
      setText(this.error, err.message);
    }
  }

  /** The table's query: the loop's heater and sensor, the set point typed (if any). @param {number} [setpoint] */
  _query(setpoint) {
    return `?${new URLSearchParams({ ...this._pair(), ...(setpoint === undefined ? {} : { setpoint: String(setpoint) }) })}`;
  }

  _showTable(table) {
    if (!table) return;
    this.tuning = table;
    this.model = table.model;
    // The step the rows predict: the server's default, or the one typed.
    this.fields.setpoint.input.value = plain(table.setpoint);
    replaceChildren(this.table, ...tuningTable(table, this.rig, Boolean(this.pairSelect), (row) => this._use(row)));
  }

  _use(row) {
    const gains = { kp: row.Kp, ti: row.Ti, td: row.Td };
    for (const [name, value] of Object.entries(gains)) this.fields[name].input.value = plain(value);
    this.fields.setpoint.input.value = plain(this.tuning.setpoint);
    this.usedRule = `${row.rule}-${row.form}`;
    this.predicted = row.response;
  }

  /** The picked rule's prediction for the set point the run starts with (typed after the pick, too). */
  async _predictionFor(setpoint) {
    const table = this.tuning;
    if (!this.usedRule || !table || setpoint === table.setpoint) return;
    const answer = await loopApi.tuning(this.tuningRun, this._query(setpoint));
    const row = answer.table?.rows.find((r) => `${r.rule}-${r.form}` === this.usedRule && !r.error);
    this.predicted = row ? row.response : null;
  }

  async _start() {
    if (this.locked) return;
    const v = this._read(["kp", "ti", "td", "setpoint", "u", "dt", "samples"]);
    if (!v) return;
    setText(this.error, "");
    try {
      await this._predictionFor(v.setpoint);
    } catch (err) {
      setText(this.error, err.message);
      return;
    }
    /** @type {Record<string, unknown>} */
    const control = { mode: this.modeSelect.value, setpoint: v.setpoint, kp: v.kp, ti: v.ti, td: v.td, adaptive: this.adaptive.checked };
    if (this.model) control.model = [this.model.K, this.model.tau, this.model.theta];
    const pair = this._pair();
    if (pair.heater !== OWN) Object.assign(control, pair);
    this.startButton.disabled = true;
    try {
      // LSM fits the whole record, the set-point step included: it identifies in closed
      // loop, where WLSM's last samples hold a settled loop (docs/command-line.md).
      const run = await api.startRun(this.rigId, { dt: v.dt, samples: v.samples, setpoint: v.u, methods: ["lsm"], control });
      this.started(run);
    } catch (err) {
      setText(this.error, err.message);
    } finally {
      this._render();
    }
  }

  /** A run began (this page's, or anyone's: the live stream says so). */
  started(run) {
    if (!run || !run.settings?.control) return;
    this.runId = run.id;
    this.running = true;
    const c = run.settings.control;
    this.runPair = { heater: c.heater ?? OWN, sensor: c.sensor ?? "y" };
    if (this.otherHost) this.otherHost.hidden = this.runPair.heater === OWN;
    this.dt = run.dt;
    for (const key of Object.keys(this.series)) this.series[key] = [];
    replaceChildren(this.figures);
    this._poll();
    this._render();
  }

  /** The run ended: show its measured figures beside the predicted ones. */
  async ended(run) {
    if (!run || run.id !== this.runId) return;
    this.running = false;
    this._render();
    await this._poll();
    try {
      const answer = await loopApi.tuning(run.id, "");
      const cl = answer.closedLoop;
      if (!cl) return;
      const row = (key, m) => h("tr", {}, h("th", { scope: "row" }, t(key)),
        h("td", { "data-figure": `${key}-overshoot` }, num(m?.overshoot, 3)),
        h("td", { "data-figure": `${key}-settling` }, num(m?.settling_time, 4)),
        h("td", { "data-figure": `${key}-iae` }, num(m?.iae)));
      replaceChildren(this.figures, h("table", {}, h("thead", {}, h("tr", {}, h("th", {}, ""),
        h("th", { scope: "col" }, t("loop.overshoot")), h("th", { scope: "col" }, t("loop.settling")), h("th", { scope: "col" }, t("loop.iae")))),
      h("tbody", {}, row("loop.measured", cl.measured), row("loop.predicted", cl.predicted))));
      // Why the prediction may not match (a warm box, no model stored...): said beside it.
      if (cl.note) this.figures.append(h("p", { class: "hint", "data-testid": "loop-note" }, ...tParts("loop.predictionNote", { note: h("span", {}, ...loopNotes(cl.notes, cl.note)) })));
    } catch (err) {
      setText(this.error, err.message);
    }
  }

  /** A live sample: r, y, u (and the gains in adaptive mode) of the closed-loop run. */
  sample(msg) {
    const c = msg.channels;
    if (!this.running || msg.run !== this.runId || !c || c.r === undefined) return;
    const s = this.series;
    if (s.t.length >= KEEP) for (const key of Object.keys(s)) s[key].splice(0, KEEP / 4);
    // A loop on a further pair draws that sensor and heater (a kit's T2, Q2), not y and u.
    const own = this.runPair.heater === OWN;
    s.t.push(msg.t); s.r.push(c.r); s.y.push(own ? msg.y : c[this.runPair.sensor] ?? NaN); s.u.push(own ? msg.u : c[this.runPair.heater] ?? c.u_pid);
    s.kp.push(c.kp ?? NaN); s.ti.push(c.ti ?? NaN);
    s.p.push(this._predictedAt(msg.t));
    if (c.kp !== undefined) this.gainHost.hidden = false;
    this.chart.invalidate(); this.uChart.invalidate(); this.gainChart.invalidate();
  }

  _predictedAt(time) {
    const p = this.predicted;
    if (!p || !p.t.length) return NaN;
    const step = p.t.length > 1 ? p.t[1] - p.t[0] : 1;
    const i = Math.round(time / step);
    return i < p.y.length ? p.y[i] ?? NaN : NaN;
  }

  async _poll() {
    clearTimeout(this._timer);
    try {
      const rig = await loopApi.loop(this.rigId);
      const loop = rig.loop;
      if (loop) {
        const g = loop.gains;
        setText(this.status, t("loop.state", { mode: t(MODE_KEYS[loop.mode]), setpoint: num(loop.setpoint), Kp: num(g.Kp), Ti: num(g.Ti), Td: num(g.Td) }));
        const reason = loop.adaptive?.last_reason;
        // Why the tuner holds the gains, in the page's language (by its code, loopwords.js).
        replaceChildren(this.hold, ...(reason ? tParts("loop.holding", { reason: loopWord(loop.adaptive.last_word, reason) }) : []));
      }
    } catch {
      // the next poll tries again
    }
    if (this.running) this._timer = setTimeout(() => void this._poll(), POLL_MS);
  }

  /** The pair chosen (the run's own where there is no choice). */
  _pair() {
    const select = this.pairSelect;
    if (!select) return { heater: OWN, sensor: "y" };
    const option = select.selectedOptions[0];
    return { heater: select.value, sensor: option?.dataset.sensor ?? "y" };
  }

  /** Another heater chosen: the manual field starts heater 1 then, a disturbance; the manual input otherwise. */
  _pairChanged() {
    // A table of the other pair's model no longer applies: the student asks for this pair's.
    this.tuning = this.model = this.usedRule = this.predicted = null;
    replaceChildren(this.table);
    const field = this.fields.u;
    const words = this._pair().heater === OWN ? t("loop.manualInput") : t("loop.otherStart");
    field.spec.label = words;
    const label = field.input.closest(".field")?.querySelector("label");
    if (label) setText(label, words);
  }

  setLocked(locked) {
    this.locked = locked;
    this._render();
  }

  _render() {
    if (!this.form) return;
    this.form.disabled = this.locked || this.running;
    this.startButton.disabled = this.locked || this.running;
    this.liveSet.disabled = this.locked || !this.running;
  }

  destroy() {
    clearTimeout(this._timer);
    this.chart?.destroy();
    this.uChart?.destroy();
    this.gainChart?.destroy();
  }
}
