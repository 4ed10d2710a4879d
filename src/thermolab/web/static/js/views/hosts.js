// @ts-check
// Rig hosts (teachers): every remote rig's host with its link, last contact,
// version and fault, refreshed every few seconds (GET /api/agents).

import { api } from "../api.js";
import { h, serverText, setText, when } from "../dom.js";
import { t } from "../i18n.js";

const POLL_MS = 3000;

/**
 * The table of hosts.
 * @param {any[]} hosts  AgentHostOut list
 */
function hostsTable(hosts) {
  if (hosts.length === 0) return h("p", { class: "muted" }, t("hosts.none"));
  const head = ["hosts.rig", "hosts.link", "hosts.lastContact", "hosts.version", "hosts.spec", "hosts.fault", "hosts.pending"].map((key) =>
    h("th", { scope: "col", class: key === "hosts.pending" ? "num" : null }, t(key)),
  );
  const rows = hosts.map((host) =>
    h(
      "tr",
      { "data-host": String(host.rig) },
      h("td", null, String(host.rig)),
      h("td", { "data-online": host.online ? "yes" : "no" }, host.online ? t("hosts.online") : t("hosts.offline")),
      h("td", null, host.lastContact ? when(host.lastContact) : t("hosts.never")),
      h("td", null, host.version ? serverText(String(host.version)) : "–"),
      h("td", null, host.spec ? serverText(String(host.spec)) : "–"),
      h("td", { "data-fault": host.fault ? "yes" : "no" }, host.fault ? serverText(String(host.fault)) : "–"),
      h("td", { class: "num" }, String(host.pending ?? 0)),
    ),
  );
  return h(
    "div",
    { class: "table-wrap", tabindex: "0", role: "region", "aria-label": t("hosts.caption") },
    h("table", { class: "runs hosts" }, h("caption", { class: "visually-hidden" }, t("hosts.caption")), h("thead", null, h("tr", null, head)), h("tbody", null, rows)),
  );
}

export function mount(main, _params, ctx) {
  if (ctx.user?.role !== "teacher") {
    main.append(h("h1", null, t("hosts.title")), h("p", { class: "error" }, t("teacher.only")));
    return null;
  }
  const status = h("p", { class: "muted", role: "status" }, t("app.loading"));
  const box = h("div");
  main.append(h("h1", null, t("hosts.title")), h("p", { class: "lede" }, t("hosts.lede")), status, box);
  const abort = new AbortController();
  let timer = null;

  async function refresh() {
    try {
      const data = await api.agents({ signal: abort.signal });
      box.replaceChildren(hostsTable(Array.isArray(data) ? data : []));
      setText(status, "");
    } catch (err) {
      if (err.name === "AbortError") return;
      setText(status, t("hosts.failed", { error: err.message }));
    }
    if (!abort.signal.aborted) timer = setTimeout(refresh, POLL_MS);
  }
  refresh();
  return () => {
    abort.abort();
    if (timer !== null) clearTimeout(timer);
  };
}
