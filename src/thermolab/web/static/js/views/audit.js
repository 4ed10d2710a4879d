// @ts-check
// The audit log (lab administrators): who did which privileged action, on
// what, when and from where (GET /api/audit), newest first, and its CSV export.

import { api, spreadsheetUrl } from "../api.js";
import { h, serverText, setText, when } from "../dom.js";
import { t } from "../i18n.js";

/**
 * A row's detail as "name=value" pairs (the server's words, untranslated).
 * @param {Record<string, unknown> | null | undefined} detail
 */
function detailText(detail) {
  if (!detail) return "";
  return Object.entries(detail)
    .map(([name, value]) => `${name}=${typeof value === "string" ? value : JSON.stringify(value)}`)
    .join("; ");
}

/**
 * The table of rows.
 * @param {any[]} rows  AuditOut list
 */
function auditTable(rows) {
  if (rows.length === 0) return h("p", { class: "muted" }, t("audit.none"));
  const head = ["audit.when", "audit.actor", "audit.action", "audit.target", "audit.address", "audit.detail"].map((key) =>
    h("th", { scope: "col" }, t(key)),
  );
  const body = rows.map((row) =>
    h(
      "tr",
      { "data-action": String(row.action) },
      h("td", null, when(row.at)),
      h("td", null, String(row.actor)),
      h("td", null, h("code", null, String(row.action))),
      h("td", null, String(row.target)),
      h("td", null, row.address ? String(row.address) : "–"),
      h("td", null, serverText(detailText(row.detail))),
    ),
  );
  return h(
    "div",
    { class: "table-wrap", tabindex: "0", role: "region", "aria-label": t("audit.caption") },
    h("table", { class: "runs audit" }, h("caption", { class: "visually-hidden" }, t("audit.caption")), h("thead", null, h("tr", null, head)), h("tbody", null, body)),
  );
}

export function mount(main, _params, ctx) {
  if (ctx.user?.admin !== true) {
    main.append(h("h1", null, t("audit.title")), h("p", { class: "error" }, t("audit.only")));
    return null;
  }
  const status = h("p", { class: "muted", role: "status" }, t("app.loading"));
  const box = h("div");
  main.append(
    h("h1", null, t("audit.title")),
    h("p", { class: "lede" }, t("audit.lede")),
    h(
      "p",
      null,
      h("a", { href: "/api/audit.csv", download: "thermolab-audit.csv" }, t("audit.csv")),
      " · ",
      h("a", { href: spreadsheetUrl("/api/audit.csv"), download: "thermolab-audit.csv", id: "audit-sheet-link" }, t("csv.spreadsheet")),
    ),
    status,
    box,
  );
  const abort = new AbortController();
  (async () => {
    try {
      const rows = await api.audit({ signal: abort.signal });
      box.replaceChildren(auditTable(Array.isArray(rows) ? rows : []));
      setText(status, "");
    } catch (err) {
      if (err.name === "AbortError") return;
      setText(status, t("audit.failed", { error: err.message }));
    }
  })();
  return () => abort.abort();
}
