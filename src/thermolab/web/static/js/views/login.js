// Log in: a plain form; the server sets an HttpOnly session cookie.

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";

export function mount(main, { query }, ctx) {
  if (ctx.user) {
    ctx.navigate("/");
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
  const submit = h("button", { type: "submit", class: "primary" }, "Log in");
  const form = h(
    "form",
    { class: "card narrow", novalidate: true, "aria-describedby": "login-error" },
    h("div", { class: "field" }, h("label", { for: "login-username" }, "User name"), username),
    h("div", { class: "field" }, h("label", { for: "login-password" }, "Password"), password),
    error,
    submit,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    if (!username.value.trim() || !password.value) {
      setText(error, "Enter your user name and password.");
      (username.value.trim() ? password : username).focus();
      return;
    }
    submit.disabled = true;
    setText(submit, "Logging in…");
    try {
      await api.login(username.value.trim(), password.value);
      announce("Logged in.");
      await ctx.afterLogin(query.get("next"));
    } catch (err) {
      setText(error, err.message);
      password.select();
      password.focus();
    } finally {
      submit.disabled = false;
      setText(submit, "Log in");
    }
  });
  main.append(
    h("h1", null, "Log in to ThermoLab"),
    h(
      "p",
      { class: "lede" },
      "Identify the model of a temperature control system on a shared rig: watch live, ask for control, run the paper's three methods.",
    ),
    form,
  );
  return null;
}
