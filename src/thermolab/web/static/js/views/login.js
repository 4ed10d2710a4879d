// @ts-check
// Log in: a plain form; the server sets an HttpOnly session cookie.

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { t } from "../i18n.js";

export function mount(main, { query }, ctx) {
  if (ctx.user) {
    ctx.navigate(ctx.landing(query.get("next")));
    return null;
  }
  const error = h("p", { class: "error", id: "login-error", role: "alert" });
  const username = h("input", {
    id: "login-username",
    name: "username",
    autocomplete: "username",
    autocapitalize: "none",
    spellcheck: "false",
    required: true,
  });
  const password = h("input", {
    id: "login-password",
    name: "password",
    type: "password",
    autocomplete: "current-password",
    required: true,
  });
  const submit = h("button", { type: "submit", class: "primary" }, t("login.submit"));
  const form = h(
    "form",
    { class: "card narrow", novalidate: true, "aria-describedby": "login-error" },
    h("div", { class: "field" }, h("label", { for: "login-username" }, t("login.username")), username),
    h("div", { class: "field" }, h("label", { for: "login-password" }, t("login.password")), password),
    error,
    submit,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    if (!username.value.trim() || !password.value) {
      setText(error, t("login.missing"));
      (username.value.trim() ? password : username).focus();
      return;
    }
    submit.disabled = true;
    setText(submit, t("login.busy"));
    try {
      await api.login(username.value.trim(), password.value);
      announce(t("login.done"));
      await ctx.afterLogin(query.get("next"));
    } catch (err) {
      setText(error, err.message);
      password.select();
      password.focus();
    } finally {
      submit.disabled = false;
      setText(submit, t("login.submit"));
    }
  });
  main.append(
    h("h1", null, t("login.heading")),
    h(
      "p",
      { class: "lede" },
      t("login.lede"),
    ),
    form,
    h("p", null, h("a", { href: "#/enrol", id: "login-enrol" }, t("login.enrol"))),
    h("p", null, h("a", { href: "#/privacy", id: "login-privacy" }, t("privacy.heading"))),
  );
  return null;
}
