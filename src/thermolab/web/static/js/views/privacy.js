// @ts-check
// The privacy page (LGPD, like the GDPR): what the lab keeps about a person,
// why, for how long, and how they download it or ask for its removal. Open to
// everyone (linked from the login page and the account page); every word is
// the catalogue's.

import { api } from "../api.js";
import { h, setText } from "../dom.js";
import { t } from "../i18n.js";

const KEPT = ["privacy.account", "privacy.runs", "privacy.handins", "privacy.bookings", "privacy.logins", "privacy.audit"];

/**
 * @param {HTMLElement} main
 * @param {any} _route
 * @param {any} ctx
 */
export function mount(main, _route, ctx) {
  // The operator's retention period: filled in when the lab has said it.
  const automatic = h("p", { id: "privacy-automatic" });
  api
    .privacy()
    .then((policy) => {
      const months = policy.retentionMonths;
      if (months === null || months === undefined) setText(automatic, t("privacy.retentionNone"));
      else if (policy.retentionAction === "delete") setText(automatic, t("privacy.retentionDelete", { count: months }));
      else setText(automatic, t("privacy.retentionPseudonymise", { count: months }));
    })
    .catch(() => automatic.remove()); // the rest of the page stands without it
  const download = ctx.user
    ? h("a", { class: "button", href: api.myDataUrl(), download: `thermolab-${ctx.user.username}.json`, id: "privacy-download" }, t("account.dataDownload"))
    : h("a", { href: "#/login", id: "privacy-login" }, t("privacy.loginFirst"));
  main.append(
    h(
      "article",
      { id: "privacy" },
      h("h1", null, t("privacy.heading")),
      h("p", { class: "lede" }, t("privacy.lede")),
      h("h2", null, t("privacy.whatHeading")),
      h("ul", { id: "privacy-kept" }, KEPT.map((key) => h("li", null, t(key)))),
      h("h2", null, t("privacy.whyHeading")),
      h("p", null, t("privacy.why")),
      h("h2", null, t("privacy.howLongHeading")),
      h("p", { id: "privacy-retention" }, t("privacy.untilRemoved")),
      automatic,
      h("h2", null, t("privacy.rightsHeading")),
      h("p", null, t("privacy.export")),
      h("p", null, download),
      h("p", null, t("privacy.remove")),
    ),
  );
  return null;
}
