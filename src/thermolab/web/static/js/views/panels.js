// @ts-check
// The paper's three panels (section II, Figs. 6–8), as tabs:
//   1. step response + least squares (SRM and LSM together),
//   2. moving-window least squares (MALSM),
//   3. weighted least squares (WLSM: adds γ, pmax and the initial parameters).
// Each takes the sample time, the number of samples and an initial set point
// (or the Automatic square wave); START begins the run, the set point can be
// changed while it runs, END closes it and the model is shown.
//
// This module holds the tabs, the lock and the commands; panels/definitions.js
// says what each panel asks for, panels/form.js builds and checks its forms and
// panels/results.js shows its run. The server's own message is shown when it
// refuses. The forms are locked for anyone who is not the controller, and
// unlock as soon as they are. Each panel also says how the operating point is
// handled (RunIn.offset): "auto" leaves it to the data (the library decides per
// record), and the run's result says what was used and found.

import { h, setParts, setText } from "../dom.js";
import { checkNumber } from "../validate.js";
import { panelOfRun, runPair } from "../runspec.js";
import { panelDefinitions } from "./panels/definitions.js";
import { buildPanelView, checkPanel } from "./panels/form.js";
import { idleParts, otherRunText, renderProgress, renderResults, runningText } from "./panels/results.js";
import { t } from "../i18n.js";

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
    const tablist = h("div", { role: "tablist", class: "tabs", "aria-label": t("panels.tabs") });
    this.notice = h("p", { class: "lock-notice", "data-testid": "lock-notice", role: "status" });
    this.el = h(
      "section",
      { class: "card panels", "aria-labelledby": "panels-heading" },
      h("h2", { id: "panels-heading" }, t("panels.heading")),
      this.notice,
      tablist,
    );
    const on = {
      start: (view) => void this._start(view),
      setpoint: (view) => void this._setpoint(view),
      end: (view) => void this._end(view),
    };
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
      const view = buildPanelView(def, limits, panelId, tabId, on);
      renderResults(view, null);
      this.views.push(view);
      this.el.append(view.el);
    });
    parent.append(this.el);
    this.select(0, false);
    this.setLocked(true, t("lock.connecting"));
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

  async _start(view) {
    if (this.locked) return;
    const checked = checkPanel(view);
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

  /**
   * Lock (watching) or unlock (controlling) every control, without a reload.
   * @param {boolean} locked
   * @param {string} [reason]
   * @param {boolean} [repeatsRole]  the reason only repeats the access card's role (a phone leaves it out)
   */
  setLocked(locked, reason = "", repeatsRole = false) {
    this.locked = locked;
    this.lockReason = reason;
    this.notice.toggleAttribute("data-repeats-role", repeatsRole);
    this._renderLock();
  }

  /** The current run (normalised by runspec.readRun) or null. */
  setRun(run) {
    this.run = run;
    this.estimatesChanged();
    this._renderLock();
  }

  /** The view of the panel the current run belongs to (undefined: no run). */
  _runView() {
    if (!this.run) return undefined;
    const panel = panelOfRun(this.run);
    return this.views.find((v) => v.def.id === panel);
  }

  /** A new estimate (live protocol) of the current run. */
  estimatesChanged() {
    const view = this._runView();
    if (view) renderResults(view, this.run);
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
      if (mine && view.pair) {
        // The run's own pair, whoever started it (a watcher, a page opened mid-run).
        const pair = runPair(this.run);
        view.pair.value = `${pair.input}>${pair.output}`;
      }
      view.runFieldset.disabled = this.locked || !mine;
      const automaticRun = mine && Boolean(this.run.signal);
      view.spInput.disabled = view.spButton.disabled = this.locked || !mine || automaticRun;
      view.endButton.disabled = this.locked || !mine;
      // The set point and END stay in place (disabled until this panel's run starts), so
      // that the action bar does not jump when START is pressed.
      renderProgress(view, mine ? this.run : null, this.run?.samples ?? 0);
      if (mine) setText(view.status, runningText(this.run, this.run.samples ?? 0));
      else if (running) setText(view.status, otherRunText(runPanel, this.defs.find((d) => d.id === runPanel)?.number));
      else setParts(view.status, idleParts(this.run, view.def.id));
    }
  }

  /** Progress of the current run (called on every sample; cheap). */
  progress(k) {
    if (!this.run || this.run.status !== "running") return;
    this.run.samples = k + 1;
    const view = this._runView();
    if (view) {
      setText(view.status, runningText(this.run, k + 1));
      renderProgress(view, this.run, k + 1);
    }
  }
}
