// The lobby: every rig with its state, controller, watchers and queue.
// Polled (every rig page has its own live socket; the lobby needs only a glance).

import { api } from "../api.js";
import { h, setText } from "../dom.js";
import { readRig, stateLabel } from "../shapes.js";

const POLL_MS = 3000;

export function mount(main, _params, ctx) {
  const status = h("p", { class: "muted", role: "status" });
  const list = h("ul", { class: "rig-list", "aria-label": "Rigs" });
  main.append(
    h("h1", null, "Rigs"),
    h("p", { class: "lede" }, "Choose a rig to watch it live. Anyone may watch; one person at a time controls a rig, the others wait in a queue."),
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
      setText(status, rigs.length ? "" : "The lab has no rigs.");
    } catch (err) {
      if (err.name === "AbortError") return;
      setText(status, `Could not load the rigs: ${err.message}`);
    }
    if (!abort.signal.aborted) timer = setTimeout(refresh, POLL_MS);
  }

  /** Update in place, so that focus and the reader's position survive a refresh. */
  function renderList(rigs) {
    const existing = new Map([...list.children].map((li) => [li.dataset.rig, li]));
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
    h("h2", { id: headingId }, h("a", { href: `#/rig/${encodeURIComponent(rig.id)}`, class: "rig-link" }, rig.title)),
    h("p", { class: "rig-id muted" }, rig.id),
    h(
      "dl",
      { class: "facts" },
      h("dt", null, "State"),
      h("dd", null, h("span", { class: "badge", "data-field": "state" })),
      h("dt", null, "Controller"),
      h("dd", { "data-field": "controller" }),
      h("dt", null, "Watching"),
      h("dd", { "data-field": "watchers" }),
      h("dt", null, "Queue"),
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
  setText(f("controller"), a.controller ? (a.controller === me ? `${a.controller} (you)` : a.controller) : "nobody");
  setText(f("watchers"), String(a.watchers));
  let queue = a.queueSize === 0 ? "empty" : `${a.queueSize} waiting`;
  if (a.queuePosition) queue += ` (you are number ${a.queuePosition})`;
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
