// @ts-check
// Deep linking (LTI 1.3): the teacher came from the LMS's activity picker and
// chooses rigs or guide pages to place in the course. The choice is a plain
// form post: the server answers a page that posts the signed choice back to
// the LMS (lab/http/lti_pages.py), so it leaves this app.

import { ltiApi } from "../lti-api.js";
import { h, setText } from "../dom.js";
import { t } from "../i18n.js";

/**
 * @param {HTMLElement} main
 * @param {{params: string[]}} route
 */
export function mount(main, { params }) {
  const key = params[0];
  const error = h("p", { class: "error", id: "deeplink-error", role: "alert" });
  const list = h("fieldset", { id: "deeplink-items" }, h("legend", null, t("deeplink.choose")));
  const submit = h("button", { type: "submit", class: "primary" }, t("deeplink.submit"));
  const form = h("form", { class: "card", id: "deeplink-form", method: "post", action: `/api/lti/deep-links/${encodeURIComponent(key)}` }, list, error, submit);
  form.addEventListener("submit", (ev) => {
    if (!form.querySelector("input:checked")) {
      ev.preventDefault();
      setText(error, t("deeplink.none"));
    }
  });
  main.append(h("h1", null, t("deeplink.heading")), form);
  ltiApi
    .deepLink(key)
    .then((offer) => {
      setText(list.querySelector("legend") ?? list, t("deeplink.chooseFor", { platform: offer.platform }));
      const type = offer.acceptMultiple ? "checkbox" : "radio";
      for (const item of offer.items) {
        const id = `deeplink-${item.target.replace(/[^a-z0-9-]/gi, "-")}`;
        const kinds = { rig: "deeplink.rig", assignment: "deeplink.assignment" };
        const label = t(kinds[item.kind] ?? "deeplink.guide", { title: item.title });
        list.append(h("div", { class: "field check" }, h("input", { type, id, name: "target", value: item.target }), h("label", { for: id }, label)));
      }
    })
    .catch((err) => setText(error, err.message));
  return null;
}
