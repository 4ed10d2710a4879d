// @ts-check
// Choose a new password: the page a login with a temporary password (a class
// list's or a teacher's reset) is kept on until the password is changed.

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { t } from "../i18n.js";

/**
 * @param {HTMLElement} main
 * @param {any} _route
 * @param {any} ctx
 */
export function mount(main, _route, ctx) {
  const error = h("p", { class: "error", id: "password-error", role: "alert" });
  const current = h("input", { id: "password-current", type: "password", autocomplete: "current-password", required: true });
  const fresh = h("input", { id: "password-new", type: "password", autocomplete: "new-password", minlength: "12", required: true });
  const submit = h("button", { type: "submit", class: "primary" }, t("password.submit"));
  const form = h(
    "form",
    { class: "card narrow", novalidate: true, "aria-describedby": "password-error" },
    h("div", { class: "field" }, h("label", { for: "password-current" }, t("password.current")), current),
    h("div", { class: "field" }, h("label", { for: "password-new" }, t("password.new")), fresh),
    h("p", { class: "muted" }, t("enrol.passwordHelp")),
    error,
    submit,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    submit.disabled = true;
    try {
      await api.changePassword(ctx.user.username, current.value, fresh.value);
      announce(t("password.done"));
      await ctx.afterLogin("/");
    } catch (err) {
      setText(error, err.message);
    } finally {
      submit.disabled = false;
    }
  });
  const lede = ctx.user?.mustChangePassword ? t("password.temporary") : t("password.lede");
  main.append(h("h1", null, t("password.heading")), h("p", { class: "lede" }, lede), form);
  return null;
}
