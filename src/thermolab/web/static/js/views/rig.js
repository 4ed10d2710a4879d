// @ts-check
// The rig page: live image, live charts (with the identified model laid over
// the data), the current estimates, the convergence of the recursive methods,
// the access panel, the paper's three panels and the closed loop (closedloop.js). Everything live comes over
// one WebSocket (LiveClient); commands go over HTTP.
//
// This module follows the rig (state, access, limits) and hands each part what
// it shows: rig/header.js, rig/connection.js, rig/camera.js, rig/readout.js,
// rig/furtherinputs.js (a kit's heater 2), rig/runshow.js (the run on show:
// rig/livecharts.js, rig/convergence.js),
// access.js and panels.js; rig/lock.js says why the panels are locked;
// rig/pace.js says how fast the rig runs and how long a turn lasts;
// rig/notice.js says what happened to my turn and run; rig/reach.js follows
// whether the lab answers at all (and locks everything while it does not).

import { ApiError, api } from "../api.js";
import { h } from "../dom.js";
import { LiveClient } from "../live.js";
import { buildRunSpec, readRun } from "../runspec.js";
import { hasProperty, openapi } from "../schema.js";
import { readAccess, readRig } from "../shapes.js";
import { AccessPanel } from "./access.js";
import { ClosedLoopPanel } from "./closedloop.js";
import { GuideDrawer, PANEL_SECTIONS } from "./guide.js";
import { Panels } from "./panels.js";
import { panelLimits } from "./panels/definitions.js";
import { Camera } from "./rig/camera.js";
import { clearConnection, showConnection } from "./rig/connection.js";
import { RigHeader } from "./rig/header.js";
import { paceText } from "./rig/pace.js";
import { lockReason, lockRepeatsRole } from "./rig/lock.js";
import { Readout } from "./rig/readout.js";
import { FurtherInputs, levelsOf, loopHeaterOf } from "./rig/furtherinputs.js";
import { TurnNotice } from "./rig/notice.js";
import { NextChance } from "./rig/chance.js";
import { Reachability } from "./rig/reach.js";
import { RunShow } from "./rig/runshow.js";
import { t } from "../i18n.js";

export { WINDOW } from "./rig/livecharts.js";

/** Reading the rig over HTTP while the live socket is down. */
const POLL_MS = 3000;

export function mount(main, { params, query }, ctx) {
  const rigId = params[0];
  ctx.setTitle(t("rig.title", { rig: rigId }));
  const page = new RigPage(main, rigId, ctx.user);
  // A link placed in an LMS (LTI deep linking) may open the guide at a section.
  const section = query?.get("guide");
  if (section) void page.guide.open(section);
  return () => page.destroy();
}

class RigPage {
  constructor(parent, rigId, user) {
    this.rigId = rigId;
    // One box for the page, so that the phone layout can order its parts (css: .rig-page).
    const main = h("div", { class: "rig-page" });
    parent.append(main);
    this.rig = null;
    this._destroyed = false;
    /** The server's OpenAPI document, once read (what the run request may carry). */
    this.schemaDoc = null;
    this._askedHistory = false;
    this._pollTimer = 0;
    this.reach = null;
    this.header = new RigHeader(main, this.rigId);
    this.notice = new TurnNotice(main, this.rigId);
    this.chance = new NextChance(main, this.rigId);
    const grid = h("div", { class: "rig-grid" });
    main.append(grid);
    const side = h("div", { class: "rig-side" });
    grid.append(side);
    this.camera = new Camera(side, this.rigId);
    this.access = new AccessPanel(side, this.rigId, {
      onError: (m) => this._error(m),
      onChange: () => this._updateLock(),
      onRefresh: () => void this._refresh(),
      onTurnEnded: () => {
        void this.notice.turnEnded();
        void this.chance.refresh();
      },
      onTurnStarted: () => this.notice.clear(),
      // The control routes answer with the rig as the caller now sees it.
      onAnswer: (answer) => {
        if (answer && typeof answer === "object" && "access" in answer && answer.access) {
          const rig = readRig(answer);
          this._setState(rig.state, rig.detail);
          this.access.update(rig.access);
        }
      },
    });
    this.readout = new Readout(side);
    this.further = new FurtherInputs(side, this.rigId, (name, applied) => {
      if (applied !== null) this.readout.setLevel(name, applied);
    });

    // The three panels (rebuilt once the rig's limits are known).
    this.panelsHost = h("div", { class: "panels-host" });
    main.append(this.panelsHost);
    this.panelActions = {
      start: (panel, values, automatic) => this._start(panel, values, automatic),
      setpoint: (u) => api.setInput(this.rigId, u),
      end: () => api.stopRun(this.rigId),
    };
    this.panels = new Panels(this.panelsHost, panelLimits(null, null), this.panelActions);
    this.show = new RunShow(grid, main, () => this.panels);
    // The fourth panel: a PID on the output (closedloop.js).
    this.loop = new ClosedLoopPanel(main, rigId);
    // The guide opens beside the panel in use, at that panel's steps (guide.js).
    this.guide = new GuideDrawer(main, rigId, user);
    this._addGuideButtons();
    this.loop.el.querySelector("h2")?.after(this.guide.button("panel-4"));
    this.client = new LiveClient(rigId, {
      onMessage: (msg) => this._onMessage(msg),
      onStatus: (s) => this._onStatus(s),
    });
    this.reach = new Reachability({
      access: this.access,
      client: this.client,
      notice: this.notice,
      currentRun: () => this.show.run,
      poll: () => {
        clearTimeout(this._pollTimer);
        void this._poll();
      },
      updateLock: () => this._updateLock(),
    });
    this._online = () => this.client.reconnectNow();
    window.addEventListener("online", this._online);
    this.client.start();
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
        this.reach?.set(true);
        if (this.client.state !== "open" || !this.rig) {
          this._setRig(rig);
          this.access.update(rig.access);
        }
        if (this.client.state !== "open" && this.show.run?.status === "running") await this._pollRun();
      } catch (err) {
        // Not the API's answer but a fault of this page's code: reported (the browser's
        // console, the tests' page errors), never retried in silence every few seconds.
        if (!(err instanceof ApiError)) reportError(err);
        else if (err.status === 404) {
          this._error(err.message);
          return;
        } else if (err.status === 0 && this.client.state !== "open") this.reach?.set(false);
      }
    }
    clearTimeout(this._pollTimer);
    this._pollTimer = setTimeout(() => void this._poll(), POLL_MS);
  }

  /** Read the rig now (the access panel asks near the end of a turn: may it be extended?). */
  async _refresh() {
    try {
      const rig = readRig(await api.rig(this.rigId));
      if (!this._destroyed) this.access.update(rig.access);
    } catch {
      // the next poll or socket message brings it
    }
  }

  /** Read the rig's actuators now (after a run's end, which puts them at their defaults). */
  async _readActuators() {
    try {
      const rig = readRig(await api.rig(this.rigId));
      if (this._destroyed) return;
      this.readout.setFurther(rig.actuators);
      this.further.follow(levelsOf(rig.actuators), true);
    } catch {
      // the next poll or hello brings them
    }
  }

  /** Without the socket, follow one's own run over HTTP (progress, estimates, its end). */
  async _pollRun() {
    let run;
    try {
      run = readRun(await api.run(this.show.run.id));
    } catch {
      return; // someone else's run (403): only the socket shows it
    }
    if (!this._destroyed && run) this.show.polled(run);
  }

  // -- live messages --------------------------------------------------------------------

  _onStatus(s) {
    if (this.reach && !this.reach.status(s)) return; // the line says the lab cannot be reached
    showConnection(
      s,
      () => this.client.state === "open",
      () => this._error(t("rig.noSuchRig", { rig: this.rigId })),
    );
  }

  _onMessage(msg) {
    if (msg.history) {
      // What the server held from before we came: only the current run's samples,
      // estimates and a notice that its replay skipped samples matter (the hello
      // already said what the state is).
      const current = this.show.run?.status === "running" ? this.show.run.id : null;
      const kept = msg.type === "sample" || msg.type === "estimate" || msg.type === "truncated";
      if (!kept || current === null || msg.run !== current) return;
    }
    switch (msg.type) {
      case "hello":
        this._setRig(readRig(msg.rig));
        this.access.update(readAccess(msg.access));
        // Joined during a closed loop on heater 2: its field is the PID's.
        this.further.setDriven(msg.run?.status === "running" ? loopHeaterOf(msg.run) : null);
        if (this.show.set(readRun(msg.run)) && !this._askedHistory) {
          // Joined half-way through a run: ask the server for all it holds (the
          // run's samples from the store, the recent estimates) once.
          this._askedHistory = true;
          this.client.replayAll();
        }
        break;
      case "sample":
        this.readout.update(msg);
        this.further.follow(msg.channels ?? {});
        this.show.sample(msg);
        this.loop.sample(msg);
        break;
      case "estimate":
        this.show.estimate(msg);
        break;
      case "truncated":
        this.show.charts.truncated(msg);
        break;
      case "run":
        this.show.event(msg);
        if (msg.event === "started") {
          this.loop.started(msg.run);
          this.further.setDriven(loopHeaterOf(msg.run));
        } else {
          this.further.setDriven(null);
          void this.loop.ended(msg.run);
          void this._readActuators(); // the run's end rested them: the rig says where
        }
        break;
      case "access":
        this.access.update(readAccess(msg.access));
        break;
      case "state":
        this._setState(msg.state, msg.detail);
        break;
      case "error":
        this._error(msg.detail ?? t("rig.refused"));
        break;
      default:
        break; // unknown types are for newer clients
    }
  }

  _setRig(rig) {
    const first = this.rig === null;
    this.rig = rig;
    this.header.setTitle(rig.title || rig.id);
    this.header.setPace(paceText(rig));
    this.access.setTurnLength(rig.limits.controlTimeLimit ?? null);
    if (first) {
      this.readout.setUnits(rig.inputUnit, rig.outputUnit);
      this.further.setActuators(rig.actuators);
      this.show.charts.setFurther(rig);
      // The panels' ranges come from the rig and the server's schema; both are
      // known before the panels unlock (they are locked until access is known).
      void openapi().then((doc) => {
        if (this._destroyed) return;
        this.schemaDoc = doc;
        this._rebuildPanels(panelLimits(rig, doc));
      });
    }
    this.readout.setFurther(rig.actuators, rig.outputs);
    this.further.follow(levelsOf(rig.actuators), true);
    this._setState(rig.state, rig.detail);
  }

  _rebuildPanels(limits) {
    const selected = this.panels.selected;
    this.panelsHost.replaceChildren();
    const panels = new Panels(this.panelsHost, limits, this.panelActions);
    panels.select(selected, false);
    this.panels = panels;
    this._addGuideButtons();
    this._updateLock();
    if (this.show.run) panels.setRun(this.show.run);
  }

  _addGuideButtons() {
    for (const view of this.panels.views) {
      const section = PANEL_SECTIONS[view.def.id];
      if (section) view.el.prepend(this.guide.button(section));
    }
  }

  _setState(state, detail) {
    if (this.rig) this.rig.state = state;
    this.header.setState(state, detail);
    this.access.setRigState(state);
    this._updateLock();
  }

  _updateLock() {
    const unreachable = this.reach?.reachable === false;
    const reason = unreachable ? t("turn.locked") : lockReason(this.access.access, this.rig?.state);
    this.panels.setLocked(Boolean(reason), reason, !unreachable && lockRepeatsRole(this.access.access, this.rig?.state));
    this.loop.setLocked(Boolean(reason));
    this.further.setLocked(Boolean(reason));
  }

  // -- commands -------------------------------------------------------------------------

  async _start(panel, values, automatic) {
    const spec = buildRunSpec(panel, values, automatic, {
      w0: hasProperty(this.schemaDoc, "RunIn", "w0"),
      offset: hasProperty(this.schemaDoc, "RunIn", "offset"),
    });
    const run = readRun(await api.startRun(this.rigId, spec));
    if (run && this.show.run?.id !== run.id) {
      this.show.started(run);
      this.show.charts.updateOverlayChoices();
    }
  }

  _error(message) {
    this.header.error(message);
  }

  destroy() {
    this._destroyed = true;
    this.client.stop();
    window.removeEventListener("online", this._online);
    clearTimeout(this._pollTimer);
    this.header.destroy();
    this.camera.destroy();
    this.chance.destroy();
    this.access.destroy();
    this.show.destroy();
    this.loop.destroy();
    clearConnection();
  }
}
