// The paper's three panels (section II, Figs. 6–8), as tabs:
//   1. step response + least squares (SRM and LSM together),
//   2. moving-window least squares (MALSM),
//   3. weighted least squares (WLSM: adds γ, pmax and the initial parameters).
// Each takes the sample time, the number of samples and an initial set point
// (or the Automatic square wave); START begins the run, the set point can be
// changed while it runs, END closes it and the model is shown.
//
// Every field shows its allowed range and is checked before anything is sent;
// the server's own message is shown when it refuses. The forms are locked for
// anyone who is not the controller, and unlock as soon as they are. Each panel
// also says how the operating point is handled (RunIn.offset): "auto" lets the
// lab remove the first sample of a rig at rest and fit the operating point of
// a warm one, and the run's result says which it did and why.

import { h, nextId, setText } from "../dom.js";
import { fmt, PAPER_W0 } from "../model.js";
import { checkAll, checkNumber, rangeText } from "../validate.js";
import { methodName, methodTitle, panelOfRun } from "../runspec.js";

/**
 * @typedef {import("../validate.js").FieldSpec & {name: string, value: number | string,
 *   hint?: string, step?: string, automaticOnly?: boolean, manualOnly?: boolean}} FieldDef
 */

/**
 * Conservative ranges used until the server's own (from /openapi.json) are
 * known; the panels are locked until then anyway.
 */
export const DEFAULT_RANGES = Object.freeze({
  dt: { min: 0.01, max: 3600 },
  samples: { min: 1, max: 200000, integer: true },
  window: { min: 2, max: 100000, integer: true },
  block: { min: 2, max: 100000, integer: true },
  gamma: { min: 0, exclusiveMin: true, max: 1, exclusiveMax: true },
  pmax: { min: 0, exclusiveMin: true, max: Infinity },
});

/** The choices of RunIn.offset, as the select shows them (OFFSET_HINT says what they mean). */
export const OFFSET_LABELS = Object.freeze({
  auto: "auto (the lab decides)",
  initial: "initial",
  fit: "fit",
  none: "none",
});
const OFFSET_HINT =
  "auto: initial on a rig at rest, fit on a warm one (still cooling after a run). " +
  "initial: the first sample is the equilibrium at 0 V and is removed. " +
  "fit: a constant term is estimated with the model. none: the raw regression.";

/** How a run handled the operating point, in words (RunOut.operatingPoint). */
export function operatingPointText(op) {
  if (!op || typeof op !== "object") return "";
  if (op.used === null || op.used === undefined) return "";
  return `Operating point: ${op.reason ?? op.used}`;
}

/**
 * Field definitions of each panel.
 * @param {{inputMin: number, inputMax: number, inputUnit: string,
 *   ranges: typeof DEFAULT_RANGES, w0: boolean, offsets?: string[] | null}} limits  the
 *   rig's input range, the server's ranges for the run's settings, whether it takes
 *   initial WLSM parameters, and the operating-point modes it offers (null: none)
 */
export function panelDefinitions(limits) {
  const r = { ...DEFAULT_RANGES, ...limits.ranges };
  const u = { min: limits.inputMin, max: limits.inputMax, unit: limits.inputUnit };
  const common = [
    { name: "dt", label: "Sample time T", ...r.dt, unit: "s", value: 1 },
    { name: "n", label: "Number of samples", ...r.samples, integer: true, value: 2000 },
  ];
  const setpoint = (value) => ({ name: "setpoint", label: "Initial set point", ...u, value, manualOnly: true });
  const auto = (lo, hi) => [
    { name: "low", label: "Automatic: minimum", ...u, value: lo, automaticOnly: true },
    { name: "high", label: "Automatic: maximum", ...u, value: hi, automaticOnly: true },
  ];
  // The paper's form of WLSM has no meaning at γ = 1 (α = 1 − γ = 0): refused by
  // the identification, so refused here too, whatever the schema's bound.
  const gamma = { ...r.gamma, max: Math.min(1, r.gamma.max ?? 1), exclusiveMax: true };
  const w0Note = limits.w0
    ? null
    : "This server does not take initial parameters yet: it starts WLSM from W0 = [0, 0].";
  return [
    {
      id: "srm-lsm",
      number: 1,
      title: "Step response + least squares",
      short: "1 · Step + LS",
      intro:
        "Set the sample time, the number of samples (at least 2000 for the step method) and the initial set point; press START, then change the set point to make the step (at least 1 V), and END when the output has settled. Start from a cold rig.",
      fields: [
        ...common,
        // 0 is "off"; otherwise the server's block range (checked in _check).
        { name: "block", label: "LSM also every N samples (0: only at END)", min: 0, max: r.block.max, integer: true, unit: "samples", value: 0, blockMin: r.block.min },
        setpoint(0),
        ...auto(4, 6),
      ],
      methods: ["srm", "lsm", "blockls"],
      optional: ["blockls"],
      stepHint: 10,
    },
    {
      id: "malsm",
      number: 2,
      title: "Moving-window least squares",
      short: "2 · Moving window",
      intro:
        "An estimate at every sample over the last N samples (a FIFO window). Vary the set point while it runs, or use the Automatic square wave.",
      fields: [...common, { name: "window", label: "Window", ...r.window, integer: true, unit: "samples", value: 100 }, setpoint(5), ...auto(4, 6)],
      methods: ["malsm"],
      automaticDefault: true,
      stepHint: 6,
    },
    {
      id: "wlsm",
      number: 3,
      title: "Weighted least squares",
      short: "3 · Weighted LS",
      intro:
        "Recursive least squares with forgetting factor γ and initial covariance pmax·I, started from the initial parameters W0 = [a0, b0] (the paper's W0 gives Ks = 0.0269905, Ts = 26.74 s).",
      fields: [
        ...common,
        { name: "gamma", label: "Forgetting factor γ", ...gamma, value: 0.96 },
        { name: "pmax", label: "pmax (diagonal of P)", ...r.pmax, value: 10000 },
        { name: "a0", label: "Initial a0", min: 0, max: 1, exclusiveMin: true, exclusiveMax: true, value: PAPER_W0.a, unavailable: w0Note },
        { name: "b0", label: "Initial b0", min: -1e6, max: 1e6, value: PAPER_W0.b, unavailable: w0Note },
        setpoint(2),
        ...auto(0, 4),
      ],
      methods: ["wlsm"],
      automaticDefault: true,
      stepHint: 4,
    },
  ];
}

/** What an estimate's status cell says: final or live, and why there is no model. */
export function estimateStatus(est) {
  if (!est) return "waiting";
  const when = est.final ? "final (at END)" : "live";
  return est.valid ? when : `${when}: ${est.reason ?? "no first-order model"}`;
}

export class Panels {
  /**
   * @param {HTMLElement} parent
   * @param {object} limits  see panelDefinitions
   * @param {{start: (panel: object, values: Record<string, number>, automatic: boolean) => Promise<void>,
   *   setpoint: (u: number) => Promise<void>, end: () => Promise<void>}} actions
   */
  constructor(parent, limits, actions) {
    this.limits = limits;
    this.actions = actions;
    this.defs = panelDefinitions(limits);
    this.locked = true;
    this.lockReason = "";
    this.run = null; // the current (or last shown) run, normalised
    this.tabs = [];
    this.views = [];
    const tablist = h("div", { role: "tablist", class: "tabs", "aria-label": "Identification panels" });
    this.notice = h("p", { class: "lock-notice", "data-testid": "lock-notice", role: "status" });
    this.el = h(
      "section",
      { class: "card panels", "aria-labelledby": "panels-heading" },
      h("h2", { id: "panels-heading" }, "Identification"),
      this.notice,
      tablist,
    );
    this.defs.forEach((def, i) => {
      const tabId = `tab-${def.id}`;
      const panelId = `panel-${def.id}`;
      const tab = h(
        "button",
        { type: "button", role: "tab", id: tabId, "aria-controls": panelId, "aria-selected": "false", tabindex: "-1", "data-panel": def.id },
        def.short,
      );
      tab.addEventListener("click", () => this.select(i, true));
      tab.addEventListener("keydown", (ev) => this._tabKey(ev, i));
      tablist.append(tab);
      this.tabs.push(tab);
      const view = this._panel(def, panelId, tabId);
      this.views.push(view);
      this.el.append(view.el);
    });
    parent.append(this.el);
    this.select(0, false);
    this.setLocked(true, "Connecting…");
  }

  _tabKey(ev, i) {
    const n = this.tabs.length;
    const to = { ArrowRight: (i + 1) % n, ArrowLeft: (i - 1 + n) % n, Home: 0, End: n - 1 }[ev.key];
    if (to === undefined) return;
    ev.preventDefault();
    this.select(to, true);
  }

  select(index, focus) {
    this.tabs.forEach((tab, i) => {
      const on = i === index;
      tab.setAttribute("aria-selected", String(on));
      tab.tabIndex = on ? 0 : -1;
      this.views[i].el.hidden = !on;
    });
    this.selected = index;
    if (focus) this.tabs[index].focus();
  }

  selectById(id) {
    const i = this.defs.findIndex((d) => d.id === id);
    if (i >= 0) this.select(i, false);
  }

  _panel(def, panelId, tabId) {
    const view = { def, inputs: {}, errors: {}, results: null };
    const form = h("form", { novalidate: true, class: "panel-form", "data-panel-form": def.id });
    const fieldset = h("fieldset", null, h("legend", null, `Panel ${def.number}: ${def.title}`));
    const autoId = nextId("auto");
    const autoBox = h("input", { type: "checkbox", id: autoId, name: "automatic", checked: Boolean(def.automaticDefault) });
    const autoHint = h("span", { class: "hint", id: `${autoId}-hint` });
    for (const f of def.fields) {
      if (f.automaticOnly && !view.autoRow) {
        view.autoRow = h(
          "div",
          { class: "field check" },
          autoBox,
          h("label", { for: autoId }, "Automatic (square wave)"),
          autoHint,
        );
        autoBox.setAttribute("aria-describedby", autoHint.id);
        fieldset.append(view.autoRow);
      }
      fieldset.append(this._field(view, f));
    }
    if (this.limits.offsets?.length) {
      const id = `${def.id}-offset`;
      view.offset = h(
        "select",
        { id, name: "offset", "aria-describedby": `${id}-hint` },
        this.limits.offsets.map((mode) => h("option", { value: mode }, OFFSET_LABELS[mode] ?? mode)),
      );
      fieldset.append(
        h(
          "div",
          { class: "field" },
          h("label", { for: id }, "Operating point"),
          view.offset,
          h("span", { class: "hint", id: `${id}-hint` }, OFFSET_HINT),
        ),
      );
    }
    view.automatic = autoBox;
    const updateAuto = () => {
      const on = autoBox.checked;
      for (const f of def.fields) {
        const row = view.inputs[f.name].closest(".field");
        if (f.automaticOnly) row.hidden = !on;
        if (f.manualOnly) row.hidden = on;
      }
      const dt = Number(view.inputs.dt.value);
      const freq = dt > 0 ? 1 / (10 * dt) : Number.NaN;
      setText(autoHint, `A square wave between the minimum and maximum at ${fmt(freq, 3)} Hz (ten times slower than sampling).`);
    };
    autoBox.addEventListener("change", updateAuto);
    view.inputs.dt.addEventListener("input", updateAuto);
    view.updateAuto = updateAuto;
    view.startButton = h("button", { type: "submit", class: "primary", "data-action": "start" }, "START");
    view.formError = h("p", { class: "error", role: "alert", "data-testid": "form-error" });
    fieldset.append(h("div", { class: "buttons" }, view.startButton));
    form.append(fieldset, view.formError);
    form.addEventListener("submit", (ev) => {
      ev.preventDefault();
      void this._start(view);
    });
    view.fieldset = fieldset;

    // Run controls: change the set point while running, END.
    const spId = nextId("sp");
    const spSpec = { label: "Set point", min: this.limits.inputMin, max: this.limits.inputMax, unit: this.limits.inputUnit };
    view.spInput = h("input", {
      id: spId,
      name: "setpoint-live",
      type: "text",
      inputmode: this.limits.inputMin >= 0 ? "decimal" : null,
      value: def.stepHint,
      "aria-describedby": `${spId}-range ${spId}-err`,
    });
    view.spError = h("span", { class: "field-error", id: `${spId}-err` });
    view.spButton = h("button", { type: "submit", "data-action": "setpoint" }, "Change set point");
    view.endButton = h("button", { type: "button", class: "danger", "data-action": "end" }, "END");
    view.spSpec = spSpec;
    const runForm = h(
      "form",
      { novalidate: true, class: "run-controls", "data-run-form": def.id },
      h(
        "fieldset",
        null,
        h("legend", null, "While the run is going"),
        h(
          "div",
          { class: "field" },
          h("label", { for: spId }, "Set point"),
          view.spInput,
          h("span", { class: "hint", id: `${spId}-range` }, `Allowed: ${rangeText(spSpec)}`),
          view.spError,
        ),
        h("div", { class: "buttons" }, view.spButton, view.endButton),
      ),
    );
    runForm.addEventListener("submit", (ev) => {
      ev.preventDefault();
      void this._setpoint(view);
    });
    view.endButton.addEventListener("click", () => void this._end(view));
    view.runFieldset = runForm.querySelector("fieldset");

    view.results = h("div", { class: "results", "data-testid": `results-${def.id}` });
    view.status = h("p", { class: "run-status", "data-testid": `run-status-${def.id}` });
    view.operatingPoint = h("p", { class: "hint", "data-testid": `operating-point-${def.id}` });
    view.el = h(
      "div",
      { role: "tabpanel", id: panelId, "aria-labelledby": tabId, class: "panel", tabindex: "0", "data-panel-view": def.id },
      h("p", { class: "panel-intro" }, def.intro),
      form,
      runForm,
      h("h3", null, "Model"),
      view.status,
      view.operatingPoint,
      view.results,
    );
    updateAuto();
    this._renderResults(view);
    return view;
  }

  _field(view, f) {
    const id = `${view.def.id}-${f.name}`;
    const input = h("input", {
      id,
      name: f.name,
      type: "text",
      // iOS's decimal keypad has no minus sign: offer it only where negatives are not allowed.
      inputmode: f.min >= 0 ? (f.integer ? "numeric" : "decimal") : null,
      value: f.value,
      autocomplete: "off",
      "aria-describedby": `${id}-range ${id}-err`,
      disabled: Boolean(f.unavailable),
    });
    const err = h("span", { class: "field-error", id: `${id}-err` });
    view.inputs[f.name] = input;
    view.errors[f.name] = err;
    input.addEventListener("input", () => {
      if (input.getAttribute("aria-invalid") === "true") this._showFieldError(view, f.name, null);
    });
    return h(
      "div",
      { class: "field" },
      h("label", { for: id }, f.label + (f.unit && f.unit !== "samples" ? ` (${f.unit})` : "")),
      input,
      h("span", { class: "hint", id: `${id}-range` }, f.unavailable ?? `Allowed: ${rangeText(f)}`),
      err,
    );
  }

  _showFieldError(view, name, message) {
    const input = view.inputs[name];
    if (message) {
      input.setAttribute("aria-invalid", "true");
      setText(view.errors[name], message);
    } else {
      input.removeAttribute("aria-invalid");
      setText(view.errors[name], "");
    }
  }

  /** Check the panel's fields; returns the values or null (errors shown, focus on the first). */
  _check(view) {
    const automatic = view.automatic.checked;
    const specs = {};
    const texts = {};
    for (const f of view.def.fields) {
      if ((f.automaticOnly && !automatic) || (f.manualOnly && automatic) || f.unavailable) {
        this._showFieldError(view, f.name, null);
        continue;
      }
      specs[f.name] = f;
      texts[f.name] = view.inputs[f.name].value;
    }
    const { values, errors } = checkAll(texts, specs);
    if (!errors.window && values.window !== undefined && values.n !== undefined && values.window > values.n) {
      errors.window = `Window must not exceed the number of samples (${values.n}).`;
    }
    if (automatic && !errors.low && !errors.high && !(values.low < values.high)) {
      errors.high = "Automatic: the maximum must be greater than the minimum.";
    }
    if (!errors.block && values.block > 0) {
      const min = view.def.fields.find((f) => f.name === "block").blockMin;
      if (values.block < min || values.block > values.n) {
        errors.block = `Blocks need from ${min} samples up to the number of samples (${values.n ?? "?"}), or 0 for none.`;
      }
    }
    let first = null;
    for (const f of view.def.fields) {
      const msg = errors[f.name] ?? null;
      if (specs[f.name] || msg) this._showFieldError(view, f.name, msg);
      if (msg && !first) first = view.inputs[f.name];
    }
    if (first) {
      setText(view.formError, "Please correct the highlighted fields; nothing was sent.");
      first.focus();
      return null;
    }
    setText(view.formError, "");
    if (view.offset) values.offset = view.offset.value;
    return { values, automatic };
  }

  async _start(view) {
    if (this.locked) return;
    const checked = this._check(view);
    if (!checked) return;
    view.startButton.disabled = true;
    try {
      await this.actions.start(view.def, checked.values, checked.automatic);
      setText(view.formError, "");
    } catch (err) {
      setText(view.formError, err.message);
    } finally {
      this._renderLock();
    }
  }

  async _setpoint(view) {
    const r = checkNumber(view.spInput.value, view.spSpec);
    if (!r.ok) {
      view.spInput.setAttribute("aria-invalid", "true");
      setText(view.spError, r.error);
      view.spInput.focus();
      return;
    }
    view.spInput.removeAttribute("aria-invalid");
    setText(view.spError, "");
    view.spButton.disabled = true;
    try {
      await this.actions.setpoint(r.value);
      setText(view.spError, "");
    } catch (err) {
      setText(view.spError, err.message);
    } finally {
      this._renderLock();
    }
  }

  async _end(view) {
    view.endButton.disabled = true;
    try {
      await this.actions.end();
    } catch (err) {
      setText(view.spError, err.message);
    } finally {
      this._renderLock();
    }
  }

  /** Lock (watching) or unlock (controlling) every control, without a reload. */
  setLocked(locked, reason = "") {
    this.locked = locked;
    this.lockReason = reason;
    this._renderLock();
  }

  /** The current run (normalised by runspec.readRun) or null. */
  setRun(run) {
    this.run = run;
    if (run) {
      const panel = panelOfRun(run);
      const i = this.defs.findIndex((d) => d.id === panel);
      if (i >= 0) this._renderResults(this.views[i]);
    }
    this._renderLock();
  }

  /** A new estimate (live protocol) of the current run. */
  estimatesChanged() {
    if (!this.run) return;
    const i = this.defs.findIndex((d) => d.id === panelOfRun(this.run));
    if (i >= 0) this._renderResults(this.views[i]);
  }

  _renderLock() {
    const running = this.run?.status === "running";
    setText(this.notice, this.locked ? this.lockReason : "");
    this.notice.hidden = !this.locked;
    const runPanel = this.run ? panelOfRun(this.run) : null;
    for (const view of this.views) {
      view.fieldset.disabled = this.locked || running;
      view.startButton.disabled = this.locked || running;
      const mine = running && runPanel === view.def.id;
      view.runFieldset.disabled = this.locked || !mine;
      const automaticRun = mine && Boolean(this.run.signal);
      view.spInput.disabled = view.spButton.disabled = this.locked || !mine || automaticRun;
      view.endButton.disabled = this.locked || !mine;
      view.runFieldset.closest("form").hidden = !mine;
      if (!mine) {
        setText(view.status, running ? `A ${methodTitle(runPanel)} run is going (panel ${this.defs.find((d) => d.id === runPanel)?.number ?? "?"}).` : this._idleStatus(view));
      } else {
        const k = this.run.samples ?? 0;
        const n = this.run.nSamples;
        setText(view.status, `Run #${this.run.id} running: sample ${k}${n ? ` of ${n}` : ""}${automaticRun ? " (Automatic square wave)" : ""}.`);
      }
    }
  }

  _idleStatus(view) {
    if (this.run && panelOfRun(this.run) === view.def.id) {
      return `Run #${this.run.id} ${this.run.status}${this.run.endReason ? ` (${this.run.endReason})` : ""}.`;
    }
    return "No run yet in this panel.";
  }

  /** Progress of the current run (called on every sample; cheap). */
  progress(k) {
    if (!this.run || this.run.status !== "running") return;
    this.run.samples = k + 1;
    const i = this.defs.findIndex((d) => d.id === panelOfRun(this.run));
    const view = this.views[i];
    if (!view) return;
    const n = this.run.nSamples;
    setText(view.status, `Run #${this.run.id} running: sample ${k + 1}${n ? ` of ${n}` : ""}${this.run.signal ? " (Automatic square wave)" : ""}.`);
  }

  _renderResults(view) {
    const run = this.run && panelOfRun(this.run) === view.def.id ? this.run : null;
    setText(view.operatingPoint, operatingPointText(run?.operatingPoint));
    view.operatingPoint.hidden = !view.operatingPoint.textContent;
    const asked = new Set(run ? run.methods.map(methodName) : []);
    const shown = view.def.methods.filter((m) => !(view.def.optional ?? []).includes(m) || asked.has(m));
    const rows = shown.map((m) => {
      const est = run?.estimates?.get(m) ?? null;
      return h(
        "tr",
        { "data-method": m },
        h("th", { scope: "row" }, methodTitle(m)),
        h("td", { "data-field": "K" }, est ? fmt(est.K) : "–"),
        h("td", { "data-field": "tau" }, est ? fmt(est.tau) : "–"),
        h("td", { "data-field": "k" }, est && Number.isFinite(est.k) ? String(est.k) : "–"),
        h("td", { "data-field": "status" }, estimateStatus(est)),
      );
    });
    view.results.replaceChildren(
      h(
        "div",
        { class: "table-wrap", tabindex: "0", role: "region", "aria-label": `${view.def.title}: estimates` },
        h(
        "table",
        { class: "estimates" },
        h("caption", { class: "visually-hidden" }, `${view.def.title}: current estimates`),
        h(
          "thead",
          null,
          h("tr", null, h("th", { scope: "col" }, "Method"), h("th", { scope: "col" }, "Ks"), h("th", { scope: "col" }, "Ts (s)"), h("th", { scope: "col" }, "at sample"), h("th", { scope: "col" }, "status")),
        ),
        h("tbody", null, rows),
      ),
      ),
    );
  }
}
