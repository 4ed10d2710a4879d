// @ts-check
// The teacher's view: every rig with its controller, queue and watchers;
// extend or cut a turn, end it, remove someone from a queue, take a rig out of
// service (or back); and every student's runs.

import { api } from "../api.js";
import { announce, duration, h, setText, when } from "../dom.js";
import { personName, readRig, rigTitle, stateLabel } from "../shapes.js";
import { checkNumber, rangeText } from "../validate.js";
import { runsPicker } from "./runs.js";
import { settingsSection } from "./settings.js";
import { t } from "../i18n.js";

const POLL_MS = 3000;
const EXTEND = { label: "teacher.seconds", min: -86400, max: 86400, unit: "s" };

export function mount(main, _params, ctx) {
  if (ctx.user?.role !== "teacher") {
    main.append(h("h1", null, t("nav.teacher")), h("p", { class: "error" }, t("teacher.only")));
    return null;
  }
  const status = h("p", { class: "muted", role: "status" });
  const list = h("div", { class: "teacher-rigs" });
  const runsBox = h("div", null, h("p", { class: "muted" }, t("app.loading")));
  main.append(
    h("h1", null, t("nav.teacher")),
    h("p", { class: "lede" }, t("teacher.lede")),
    h("p", null, h("a", { href: "#/hosts" }, t("teacher.hostsLink"))),
    ctx.user.admin === true ? h("p", null, h("a", { href: "#/audit" }, t("teacher.auditLink"))) : null,
    status,
    list,
    h("section", { class: "card", "aria-labelledby": "all-runs" }, h("h2", { id: "all-runs" }, t("teacher.allRuns")), runsBox),
  );
  const abort = new AbortController();
  const cards = new Map();
  let timer = null;

  async function refresh() {
    try {
      const data = await api.rigs({ signal: abort.signal });
      const rigs = (Array.isArray(data) ? data : []).map(readRig);
      for (const rig of rigs) {
        let card = cards.get(rig.id);
        if (!card) {
          card = new RigCard(rig.id, refreshSoon);
          cards.set(rig.id, card);
          list.append(card.el);
        }
        card.update(rig);
      }
      setText(status, "");
    } catch (err) {
      if (err.name === "AbortError") return;
      setText(status, t("lobby.failed", { error: err.message }));
    }
    if (!abort.signal.aborted) timer = setTimeout(refresh, POLL_MS);
  }

  function refreshSoon() {
    clearTimeout(timer);
    void refresh();
  }

  async function loadRuns() {
    try {
      const runs = await api.runs("", { signal: abort.signal });
      runsBox.replaceChildren(runsPicker(Array.isArray(runs) ? runs : [], ctx, { showUser: true, label: t("teacher.allRuns") }));
    } catch (err) {
      if (err.name === "AbortError") return;
      runsBox.replaceChildren(h("p", { class: "error" }, t("teacher.runsFailed", { error: err.message })));
    }
  }

  void refresh();
  void loadRuns();
  const tick = setInterval(() => {
    for (const card of cards.values()) card.renderTime();
  }, 1000);
  return () => {
    abort.abort();
    clearTimeout(timer);
    clearInterval(tick);
  };
}

class RigCard {
  constructor(rigId, changed) {
    this.rigId = rigId;
    this.changed = changed;
    const hid = `teacher-rig-${rigId}`;
    this.title = h("a", { href: `#/rig/${encodeURIComponent(rigId)}` });
    this.badge = h("span", { class: "badge" });
    this.facts = h("dl", { class: "facts" });
    this.f = {};
    for (const [key, label] of [["controller", t("access.controller")], ["timeLeft", t("teacher.turnEnds")], ["watchers", t("access.watchers")], ["fault", t("rigState.fault")]]) {
      this.f[key] = h("dd", { "data-field": key });
      this.facts.append(h("dt", null, label), this.f[key]);
    }
    this.message = h("p", { class: "error", role: "alert" });
    const secId = `${hid}-seconds`;
    const extend = { ...EXTEND, label: t(EXTEND.label) };
    this.seconds = h("input", { id: secId, value: "60", "aria-describedby": `${secId}-hint`, autocomplete: "off" });
    this.extendButton = h("button", { type: "submit" }, t("teacher.extend"));
    const extendForm = h(
      "form",
      { novalidate: true, class: "field inline" },
      h("label", { for: secId }, t("teacher.secondsToAdd")),
      this.seconds,
      this.extendButton,
      h("span", { class: "hint", id: `${secId}-hint` }, t("teacher.extendHint", { range: rangeText(extend) })),
    );
    extendForm.addEventListener("submit", (ev) => {
      ev.preventDefault();
      const r = checkNumber(this.seconds.value, extend);
      if (!r.ok) {
        this.seconds.setAttribute("aria-invalid", "true");
        setText(this.message, r.error);
        this.seconds.focus();
        return;
      }
      this.seconds.removeAttribute("aria-invalid");
      void this.act(() => api.extendControl(rigId, r.value), r.value >= 0 ? t("teacher.extended", { rig: rigId, seconds: r.value }) : t("teacher.cut", { rig: rigId, seconds: -r.value }));
    });
    this.endButton = h("button", { type: "button", class: "danger" }, t("teacher.end"));
    this.endButton.addEventListener("click", () => void this.act(() => api.kick(rigId, null), t("teacher.ended", { rig: rigId })));
    this.serviceButton = h("button", { type: "button" });
    this.serviceButton.addEventListener("click", () => {
      const out = this.rig?.inService;
      void this.act(() => api.setService(rigId, !out), out ? t("teacher.outOfService", { rig: rigId }) : t("teacher.inService", { rig: rigId }));
    });
    this.controlBox = h("div", null, extendForm, h("div", { class: "buttons" }, this.endButton));
    this.queue = h("ol", { class: "queue-list" });
    this.queueEmpty = h("p", { class: "muted" }, t("teacher.queueEmpty"));
    this.deadline = null;
    this.watchers = h("ul", { class: "watcher-list" });
    this.el = h(
      "section",
      { class: "card teacher-rig", "aria-labelledby": hid, "data-rig": rigId },
      h("h2", { id: hid }, this.title, " ", this.badge),
      this.facts,
      this.message,
      this.controlBox,
      h("h3", null, t("lobby.queue")),
      this.queueEmpty,
      this.queue,
      h("h3", null, t("teacher.watchers")),
      this.watchers,
      h("div", { class: "buttons" }, this.serviceButton),
      settingsSection(rigId),
    );
    this._queueKey = "";
    this._watchKey = "";
  }

  /** The controller's time left counts down between refreshes (everyone is given it). */
  renderTime() {
    const left = this.deadline === null ? null : Math.max(0, (this.deadline - Date.now()) / 1000);
    setText(this.f.timeLeft, left === null ? "–" : duration(left));
  }

  async act(fn, done) {
    setText(this.message, "");
    try {
      const answer = await fn();
      if (answer && answer.access) this.update(readRig(answer));
      announce(done);
    } catch (err) {
      setText(this.message, err.message);
    }
    this.changed();
  }

  update(rig) {
    this.rig = rig;
    this.deadline = rig.access.controller && rig.access.timeLeft !== null ? Date.now() + rig.access.timeLeft * 1000 : null;
    setText(this.title, rigTitle(rig));
    setText(this.badge, stateLabel(rig.state));
    this.badge.dataset.state = rig.state;
    const a = rig.access;
    setText(this.f.controller, a.controller ? personName(a.controller, a.controllerName, true) : t("access.nobody"));
    this.renderTime();
    setText(this.f.watchers, String(a.watchers));
    setText(this.f.fault, rig.detail ?? t("teacher.noFault"));
    this.controlBox.hidden = !a.controller;
    setText(this.serviceButton, rig.inService ? t("teacher.takeOut") : t("teacher.putBack"));
    this.serviceButton.className = rig.inService ? "danger" : "primary";
    const queue = rig.queue ?? [];
    const qKey = JSON.stringify(queue.map((q) => [q.username, q.displayName, q.position]));
    if (qKey !== this._queueKey) {
      this._queueKey = qKey;
      const hadFocus = this.queue.contains(document.activeElement);
      this.queue.replaceChildren(
        ...(queue.length
          ? queue.map((q) =>
              h(
                "li",
                null,
                t("teacher.queued", { user: personName(q.username, q.displayName, true), since: when(q.joinedAt) }) + " ",
                h("button", { type: "button", class: "link-button", "aria-label": t("teacher.removeLabel", { user: personName(q.username, q.displayName) }), onclick: () => void this.act(() => api.kick(this.rigId, q.username), t("teacher.removed", { user: q.username })) }, t("teacher.remove")),
              ),
            )
          : []),
      );
      this.queueEmpty.hidden = queue.length > 0;
      if (hadFocus) this.queue.querySelector("button")?.focus();
    }
    const watchers = rig.watcherList ?? [];
    const wKey = JSON.stringify(watchers.map((w) => [w.username, w.displayName, w.connections]));
    if (wKey !== this._watchKey) {
      this._watchKey = wKey;
      this.watchers.replaceChildren(
        ...(watchers.length
          ? watchers.map((w) => {
              const who = personName(w.username, w.displayName, true);
              return h("li", null, w.connections > 1 ? t("teacher.watcherWindows", { user: who, count: w.connections }) : who);
            })
          : [h("li", { class: "muted" }, t("access.nobody"))]),
      );
    }
  }
}
