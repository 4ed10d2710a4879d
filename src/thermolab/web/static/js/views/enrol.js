// @ts-check
// Enrol with a course code: a student makes their own account (login name,
// the name shown, a password), then is logged in.

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { t } from "../i18n.js";

/**
 * @param {HTMLElement} main
 * @param {{query: URLSearchParams}} route
 * @param {any} ctx
 */
export function mount(main, { query }, ctx) {
  const error = h("p", { class: "error", id: "enrol-error", role: "alert" });
  /** @param {string} id @param {Record<string, any>} attrs */
  const input = (id, attrs) => h("input", { id, name: id, required: true, ...attrs });
  const code = input("enrol-code", { autocomplete: "off", autocapitalize: "characters", spellcheck: "false", value: query.get("code") ?? "" });
  const username = input("enrol-username", { autocomplete: "username", autocapitalize: "none", spellcheck: "false" });
  const shown = input("enrol-name", { autocomplete: "name" });
  const password = input("enrol-password", { type: "password", autocomplete: "new-password", minlength: "12" });
  const submit = h("button", { type: "submit", class: "primary" }, t("enrol.submit"));
  /** @param {string} id @param {string} key */
  const field = (id, key, el) => h("div", { class: "field" }, h("label", { for: id }, t(key)), el);
  const form = h(
    "form",
    { class: "card narrow", novalidate: true, "aria-describedby": "enrol-error" },
    field("enrol-code", "enrol.code", code),
    field("enrol-username", "enrol.username", username),
    field("enrol-name", "enrol.displayName", shown),
    field("enrol-password", "enrol.password", password),
    h("p", { class: "muted" }, t("enrol.passwordHelp")),
    error,
    submit,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    const empty = [code, username, shown, password].find((el) => !el.value.trim());
    if (empty) {
      setText(error, t("enrol.missing"));
      empty.focus();
      return;
    }
    submit.disabled = true;
    try {
      const made = await api.enrol({ code: code.value.trim(), username: username.value.trim(), displayName: shown.value.trim(), password: password.value });
      await api.login(made.username, password.value);
      announce(t("enrol.done", { user: made.username }));
      await ctx.afterLogin("/");
    } catch (err) {
      setText(error, err.message);
    } finally {
      submit.disabled = false;
    }
  });
  main.append(h("h1", null, t("enrol.heading")), h("p", { class: "lede" }, t("enrol.lede")), form, h("p", null, h("a", { href: "#/login" }, t("enrol.haveAccount"))));
  return null;
}
