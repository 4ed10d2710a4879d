// @ts-check
// The access panel of a rig page: who controls, the queue, my place in it, the
// controller's remaining time, and the buttons to ask for or give up control.
// Changes that matter to me are announced to screen readers (live region).
// The controller is warned 60 s and 20 s before the turn ends (said in the
// polite region and shown beside the countdown, WCAG 2.2.1) and offered
// "Extend my turn" when nobody waits (the server decides: canExtend). While
// the lab cannot be reached the panel shows no role and no countdown.

import { api } from "../api.js";
import { announce, duration, durationWords, h, setText } from "../dom.js";
import { t } from "../i18n.js";
import { personName } from "../shapes.js";

/** Seconds before the end of a turn at which the controller is warned (the first also offers "extend"). */
export const WARNINGS = [60, 20];

export class AccessPanel {
  /**
   * @param {HTMLElement} parent
   * @param {string} rigId
   * @param {{onError: (msg: string) => void, onChange: () => void, onAnswer?: (answer: unknown) => void,
   *          onRefresh?: () => void, onTurnEnded?: () => void, onTurnStarted?: () => void}} hooks
   */
  constructor(parent, rigId, hooks) {
    this.rigId = rigId;
    this.hooks = hooks;
    this.access = null;
    this.rigState = "off";
    this._deadline = null; // ms timestamp when the controller's time runs out
    this._idleDeadline = null; // ms timestamp when control ends for want of a command
    this._warned = new Set();
    /** @type {number | null} seconds a turn lasts on this rig */
    this._turnLength = null;
    this._busy = false;
    /** The lab cannot be reached: nothing shown as current. */
    this.unreachable = false;
    this.role = h("p", { class: "access-role", "data-testid": "access-role" });
    this.facts = h("dl", { class: "facts" });
    this.fields = {};
    for (const [key, label] of [
      ["controller", t("access.controller")],
      ["timeLeft", t("access.timeLeft")],
      ["idleLeft", t("access.idleLeft")],
      ["turnLength", t("access.turnLength")],
      ["watchers", t("access.watchers")],
      ["queueSize", t("access.queueSize")],
      ["position", t("access.position")],
      ["wait", t("access.wait")],
    ]) {
      const dd = h("dd", { "data-field": key });
      this.fields[key] = dd;
      // Each name and value in one box (HTML allows a div around a dt/dd group), so that a
      // phone can flow the facts on a few lines without parting a name from its value.
      this.facts.append(h("div", { class: "fact", "data-fact": key }, h("dt", { "data-for": key }, label), dd));
    }
    this.askButton = h("button", { type: "button", class: "primary", "data-action": "ask" }, t("access.ask"));
    this.leaveButton = h("button", { type: "button", "data-action": "leave" }, t("access.leave"));
    this.releaseButton = h("button", { type: "button", "data-action": "release" }, t("access.release"));
    this.askButton.addEventListener("click", () => this._act("ask"));
    this.leaveButton.addEventListener("click", () => this._act("leave"));
    this.releaseButton.addEventListener("click", () => this._act("release"));
    this.extendButton = h("button", { type: "button", class: "primary", "data-action": "extend", hidden: true }, t("turn.extend"));
    this.extendButton.addEventListener("click", () => this._act("extend"));
    this.warning = h("p", { class: "time-warning", "data-testid": "time-warning", hidden: true });
    this.el = h(
      "section",
      { class: "card access", "aria-labelledby": "access-heading" },
      h("h2", { id: "access-heading" }, t("access.heading")),
      this.role,
      this.warning,
      this.facts,
      h("div", { class: "buttons" }, this.extendButton, this.askButton, this.leaveButton, this.releaseButton),
    );
    parent.append(this.el);
    this._tick = setInterval(() => this._renderTime(), 1000);
  }

  get isController() {
    return this.access?.role === "controller";
  }

  /** New access state (hello, `access` message, or an action's answer). */
  update(access) {
    const before = this.access;
    this.access = access;
    this._deadline = access.timeLeft === null ? null : Date.now() + access.timeLeft * 1000;
    this._idleDeadline = access.idleTimeLeft === null ? null : Date.now() + access.idleTimeLeft * 1000;
    this.unreachable = false;
    if (access.role !== "controller") this._warned.clear();
    this._announceChange(before, access);
    if (before?.role === "controller" && access.role !== "controller") this.hooks.onTurnEnded?.();
    if (before && before.role !== "controller" && access.role === "controller") this.hooks.onTurnStarted?.();
    this.render();
    this.hooks.onChange();
  }

  /** The lab stopped answering (true) or answers again (false, before fresh access arrives). */
  setUnreachable(unreachable) {
    if (unreachable === this.unreachable) return;
    this.unreachable = unreachable;
    if (unreachable) {
      this._deadline = null;
      this._idleDeadline = null;
    }
    this.render();
  }

  /** A turn's length on this rig (the teacher's setting in force; a new turn gets it). */
  setTurnLength(seconds) {
    this._turnLength = typeof seconds === "number" ? seconds : null;
    this.render();
  }

  setRigState(state) {
    this.rigState = state;
    this.render();
  }

  _announceChange(before, now) {
    if (!before) return;
    const rig = this.rigId;
    if (now.role !== before.role) {
      if (now.role === "controller") announce(t("access.gotControl", { rig }));
      else if (before.role === "controller") announce(t("access.lostControl", { rig }));
      else if (now.role === "queued" || now.queuePosition) {
        announce(t("access.queuedFor", { position: now.queuePosition, rig }));
      } else if (before.role === "queued") announce(t("access.leftQueue", { rig }));
      return;
    }
    if (now.queuePosition && before.queuePosition && now.queuePosition !== before.queuePosition) {
      announce(t("access.moved", { position: now.queuePosition }));
    }
    if (now.controller !== before.controller && now.role !== "controller") {
      announce(now.controller ? t("access.newController", { user: personName(now.controller, now.controllerName), rig }) : t("access.noController", { rig }));
    }
  }

  _secondsLeft() {
    return this._deadline === null ? null : Math.max(0, (this._deadline - Date.now()) / 1000);
  }

  _renderTime() {
    const idle = this._idleDeadline ? Math.max(0, (this._idleDeadline - Date.now()) / 1000) : null;
    if (this.isController && idle !== null && idle <= 30 && idle > 28 && !this._warned.has("idle")) {
      this._warned.add("idle");
      announce(t("access.idleWarning"));
    }
    if (idle !== null && idle > 30) this._warned.delete("idle");
    setText(this.fields.idleLeft, idle === null ? "–" : duration(idle));
    this.fields.idleLeft.title = t("access.idleHelp");
    const left = this._secondsLeft();
    const dd = this.fields.timeLeft;
    // Everyone sees the controller's countdown: it tells a watcher when the rig changes hands.
    setText(this.facts.querySelector('[data-for="timeLeft"]'), this.isController ? t("access.yourTimeLeft") : t("access.controllerTimeLeft"));
    setText(dd, left === null ? "–" : duration(left));
    dd.setAttribute("aria-label", left === null ? t("access.noLimit") : durationWords(left));
    if (this.isController && left !== null) {
      // A few spoken warnings, not a ticking announcement every second.
      for (const mark of WARNINGS) {
        if (left <= mark && left > mark - 2 && !this._warned.has(mark)) {
          this._warned.add(mark);
          announce(t("access.timeWarning", { time: durationWords(mark) }));
          // The server says whether the turn may be extended now (the queue may have changed).
          if (mark === WARNINGS[0]) this.hooks.onRefresh?.();
        }
      }
    }
    this._renderWarning(left);
    this._markEmpty();
  }

  /** Mark the facts that have no value now ("–"): a phone leaves them out to keep the card short. */
  _markEmpty() {
    for (const dd of Object.values(this.fields)) dd.parentElement?.toggleAttribute("data-empty", dd.textContent === "–");
  }

  /** The visible warning in the turn's last minute, with "extend" when the server allows it. */
  _renderWarning(left) {
    const soon = !this.unreachable && this.isController && left !== null && left <= WARNINGS[0];
    const extendable = soon && Boolean(this.access?.canExtend);
    this.warning.hidden = !soon;
    if (soon) {
      const time = durationWords(Math.ceil(left));
      setText(this.warning, extendable ? t("turn.endsSoonExtend", { time }) : t("turn.endsSoon", { time }));
    }
    if (this.extendButton.hidden === extendable) this.extendButton.hidden = !extendable;
    this.extendButton.disabled = this._busy;
  }

  render() {
    const a = this.access;
    if (!a || this.unreachable) {
      setText(this.role, this.unreachable ? t("turn.unreachable") : t("lock.connecting"));
      this.role.dataset.role = this.unreachable ? "unknown" : "";
      for (const b of [this.askButton, this.leaveButton, this.releaseButton, this.extendButton]) b.hidden = true;
      for (const dd of Object.values(this.fields)) setText(dd, "–");
      this._markEmpty();
      this.warning.hidden = true;
      return;
    }
    const roleText = {
      controller: t("access.roleController"),
      queued: t("access.roleQueued", { position: a.queuePosition ?? "?" }),
      watcher: t("access.roleWatcher"),
      teacher: t("access.roleTeacher"),
    };
    setText(this.role, roleText[a.role] ?? (a.queuePosition ? roleText.queued : roleText.watcher));
    this.role.dataset.role = a.role;
    setText(this.fields.controller, a.controller ? personName(a.controller, a.controllerName) : t("access.nobody"));
    setText(this.fields.turnLength, this._turnLength === null ? "–" : durationWords(this._turnLength));
    setText(this.fields.watchers, String(a.watchers));
    setText(this.fields.queueSize, String(a.queueSize));
    const queued = a.role === "queued" || (a.queuePosition !== null && a.role !== "controller");
    setText(this.fields.position, queued ? `${a.queuePosition}` : "–");
    // For a watcher the server gives the wait they would have if they asked now.
    setText(this.facts.querySelector('[data-for="wait"]'), queued ? t("access.wait") : t("access.waitIfAsked"));
    setText(this.fields.wait, a.role === "controller" ? "–" : duration(a.estimatedTimeUntilControl));
    this._renderTime();
    const usable = !["fault", "out_of_service"].includes(this.rigState);
    this.askButton.hidden = a.role === "controller" || queued;
    this.askButton.disabled = this._busy || !usable;
    this.leaveButton.hidden = !queued;
    this.leaveButton.disabled = this._busy;
    this.releaseButton.hidden = a.role !== "controller";
    this.releaseButton.disabled = this._busy;
  }

  async _act(what) {
    if (this._busy) return;
    this._busy = true;
    this.render();
    const focusAfter = what === "ask" ? null : what === "extend" ? this.releaseButton : this.askButton;
    try {
      const call = { ask: api.askControl, extend: api.moreTime }[what] ?? api.releaseControl;
      const answer = await call(this.rigId);
      this.hooks.onAnswer?.(answer);
      if (what === "extend") {
        this._warned.clear();
        announce(t("turn.extended", { time: durationWords(this._secondsLeft() ?? 0) }));
      }
    } catch (err) {
      this.hooks.onError(err.message);
    } finally {
      this._busy = false;
      this.render();
      // Keep keyboard focus on a visible button after the one pressed hides.
      const visible = [this.releaseButton, this.leaveButton, this.askButton].find((b) => !b.hidden);
      if (document.activeElement === document.body || (document.activeElement instanceof HTMLElement && document.activeElement.hidden)) (focusAfter && !focusAfter.hidden ? focusAfter : visible)?.focus();
    }
  }

  destroy() {
    clearInterval(this._tick);
  }
}
