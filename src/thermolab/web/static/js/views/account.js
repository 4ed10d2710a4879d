// @ts-check
// My account: personal API tokens for scripts and notebooks (thermolab.client,
// thermolab.tclab), and the download of everything the lab keeps about me. A token's secret is shown once, right after it is made;
// the list shows only its first characters.

import { api } from "../api.js";
import { announce, h, setText, when } from "../dom.js";
import { t } from "../i18n.js";

/**
 * @param {HTMLElement} main
 * @param {any} _route
 * @param {any} ctx
 */
export function mount(main, _route, ctx) {
  let alive = true;
  const error = h("p", { class: "error", id: "token-error", role: "alert" });
  const list = h("div", { class: "table-wrap", tabindex: "0", role: "region", "aria-label": t("account.caption") });
  const secret = h("section", { class: "card", id: "token-secret", hidden: true, "aria-live": "polite" });

  const name = h("input", { id: "token-name", name: "name", maxlength: "64", required: true, autocomplete: "off" });
  const readOnly = h("input", { id: "token-read-only", name: "readOnly", type: "checkbox" });
  const days = h("input", { id: "token-days", name: "days", type: "number", min: "1", max: "365", value: "90", inputmode: "numeric" });
  const create = h("button", { type: "submit", class: "primary" }, t("account.create"));
  const form = h(
    "form",
    { class: "card", novalidate: true, "aria-describedby": "token-error" },
    h("div", { class: "field" }, h("label", { for: "token-name" }, t("account.tokenName")), name),
    h("div", { class: "field" }, h("label", { for: "token-days" }, t("account.tokenDays")), days),
    h("div", { class: "field check" }, readOnly, h("label", { for: "token-read-only" }, t("account.tokenReadOnly"))),
    error,
    create,
  );

  async function refresh() {
    const tokens = await api.tokens();
    if (!alive) return;
    list.replaceChildren(tokenTable(tokens, revoke));
  }

  /** @param {any} token */
  async function revoke(token) {
    setText(error, "");
    try {
      await api.revokeToken(token.id);
      announce(t("account.revoked", { name: token.name }));
      await refresh();
    } catch (err) {
      setText(error, err.message);
    }
  }

  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    const label = name.value.trim();
    const lifetime = Number(days.value);
    if (!label) {
      setText(error, t("account.nameRequired"));
      name.focus();
      return;
    }
    if (!Number.isInteger(lifetime) || lifetime < 1 || lifetime > 365) {
      setText(error, t("account.daysRange"));
      days.focus();
      return;
    }
    create.disabled = true;
    try {
      const made = await api.createToken({ name: label, readOnly: readOnly.checked, days: lifetime });
      const value = h("input", { id: "token-value", readonly: true, value: made.token, class: "secret", spellcheck: "false" });
      secret.replaceChildren(
        h("h2", null, t("account.secretHeading")),
        h("p", null, t("account.created", { name: made.name })),
        h("div", { class: "field" }, h("label", { for: "token-value" }, t("account.secretLabel")), value),
        h("p", { class: "muted" }, t("account.usage")),
      );
      secret.hidden = false;
      value.focus();
      value.select();
      form.reset();
      days.value = "90";
      await refresh();
    } catch (err) {
      setText(error, err.message);
    } finally {
      create.disabled = false;
    }
  });

  main.append(
    h("h1", null, t("account.title")),
    h("p", { class: "lede" }, t("account.who", { user: ctx.user?.username ?? "" })),
    h("h2", null, t("account.tokensHeading")),
    h("p", null, t("account.tokensHelp")),
    secret,
    form,
    list,
    h("h2", null, t("account.dataHeading")),
    h("p", null, t("account.dataHelp")),
    h("p", null, h("a", { class: "button", href: api.myDataUrl(), download: `thermolab-${ctx.user?.username ?? "me"}.json`, "data-testid": "my-data" }, t("account.dataDownload"))),
    h("p", null, h("a", { href: "#/privacy", id: "account-privacy" }, t("privacy.heading"))),
  );
  refresh().catch((err) => setText(error, err.message));
  return () => {
    alive = false;
  };
}

/**
 * The user's tokens, each with a button to revoke it.
 * @param {any[]} tokens
 * @param {(token: any) => void} onRevoke
 */
function tokenTable(tokens, onRevoke) {
  if (!Array.isArray(tokens) || tokens.length === 0) return h("p", { class: "muted" }, t("account.none"));
  const rows = tokens.map((token) =>
    h(
      "tr",
      { "data-token": token.id },
      h("td", null, token.name),
      h("td", null, h("code", null, `${token.prefix}…`)),
      h("td", null, token.readOnly ? t("account.readOnly") : t("account.full")),
      h("td", null, when(token.createdAt)),
      h("td", null, token.lastUsedAt ? when(token.lastUsedAt) : t("account.never")),
      h("td", null, when(token.expiresAt)),
      h(
        "td",
        null,
        h("button", { type: "button", "aria-label": t("account.revokeOne", { name: token.name }), onclick: () => onRevoke(token) }, t("account.revoke")),
      ),
    ),
  );
  const head = ["account.colName", "account.colPrefix", "account.colAccess", "account.colCreated", "account.colLastUsed", "account.colExpires", "account.colActions"].map((key) =>
    h("th", { scope: "col" }, t(key)),
  );
  return h("table", { class: "runs" }, h("caption", { class: "visually-hidden" }, t("account.caption")), h("thead", null, h("tr", null, head)), h("tbody", null, rows));
}
