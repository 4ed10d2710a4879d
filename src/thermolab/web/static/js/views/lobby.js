// @ts-check
// The lobby: every rig with its state, controller, watchers and queue.
// Polled (every rig page has its own live socket; the lobby needs only a glance).

import { api } from "../api.js";
import { h, setText } from "../dom.js";
import { personName, readRig, rigTitle, stateLabel } from "../shapes.js";
import { t } from "../i18n.js";

const POLL_MS = 3000;

export function mount(main, _params, ctx) {
  const status = h("p", { class: "muted", role: "status" });
  const list = h("ul", { class: "rig-list", "aria-label": t("nav.rigs") });
  main.append(
    h("h1", null, t("nav.rigs")),
    h("p", { class: "lede" }, t("lobby.lede")),
    status,
    list,
  );
  const abort = new AbortController();
  let timer = null;

  async function refresh() {
    try {
      const data = await api.rigs({ signal: abort.signal });
      const rigs = (Array.isArray(data) ? data : (data?.rigs ?? [])).map(readRig);
      renderList(rigs);
      setText(status, rigs.length ? "" : t("lobby.none"));
    } catch (err) {
      if (err.name === "AbortError") return;
      setText(status, t("lobby.failed", { error: err.message }));
    }
    if (!abort.signal.aborted) timer = setTimeout(refresh, POLL_MS);
  }

  /** Update in place, so that focus and the reader's position survive a refresh. */
  function renderList(rigs) {
    const existing = new Map([...list.querySelectorAll("li")].map((li) => [li.dataset.rig, li]));
    const keep = new Set();
    for (const rig of rigs) {
      keep.add(rig.id);
      let li = existing.get(rig.id);
      if (!li) {
        li = rigCard(rig);
        list.append(li);
      }
      updateCard(li, rig, ctx);
    }
    for (const [id, li] of existing) if (!keep.has(id)) li.remove();
  }

  void refresh();
  return () => {
    abort.abort();
    if (timer !== null) clearTimeout(timer);
  };
}

function rigCard(rig) {
  const headingId = `rig-card-${rig.id}`;
  return h(
    "li",
    { class: "card rig-card", "data-rig": rig.id, "aria-labelledby": headingId },
    h("h2", { id: headingId }, h("a", { href: `#/rig/${encodeURIComponent(rig.id)}`, class: "rig-link" }, rigTitle(rig))),
    h("p", { class: "rig-id muted" }, rig.id),
    h(
      "dl",
      { class: "facts" },
      h("dt", null, t("lobby.state")),
      h("dd", null, h("span", { class: "badge", "data-field": "state" })),
      h("dt", null, t("access.controller")),
      h("dd", { "data-field": "controller" }),
      h("dt", null, t("access.watchers")),
      h("dd", { "data-field": "watchers" }),
      h("dt", null, t("lobby.queue")),
      h("dd", { "data-field": "queue" }),
    ),
  );
}

function updateCard(li, rig, ctx) {
  const f = (name) => li.querySelector(`[data-field="${name}"]`);
  const badge = f("state");
  setText(badge, stateLabel(rig.state));
  badge.dataset.state = rig.state;
  const a = rig.access;
  const me = ctx.user?.username;
  const named = a.controller ? personName(a.controller, a.controllerName) : null;
  setText(f("controller"), a.controller ? (a.controller === me ? t("lobby.you", { user: named }) : named) : t("access.nobody"));
  setText(f("watchers"), String(a.watchers));
  let queue = t("lobby.waiting", { count: a.queueSize });
  if (a.queuePosition) queue = t("lobby.waitingYou", { queue, position: a.queuePosition });
  setText(f("queue"), queue);
  if (rig.detail && (rig.state === "fault" || rig.state === "out_of_service")) {
    let note = li.querySelector(".rig-detail");
    if (!note) {
      note = h("p", { class: "rig-detail" });
      li.append(note);
    }
    setText(note, rig.detail);
  } else {
    li.querySelector(".rig-detail")?.remove();
  }
}
