// @ts-check
// The top of the rig page: its name, its state badge and detail, and a banner
// for errors that clears itself.

import { announce, h, setText } from "../../dom.js";
import { rigTitle, stateLabel } from "../../shapes.js";
import { t } from "../../i18n.js";

/** How long an error stays on the banner. */
const BANNER_MS = 15000;

export class RigHeader {
  /**
   * @param {HTMLElement} main
   * @param {string} rigId
   */
  constructor(main, rigId) {
    this.rigId = rigId;
    this.state = undefined;
    this._bannerTimer = 0;
    this.badge = h("span", { class: "badge", "data-testid": "rig-state" }, "…");
    this.detail = h("span", { class: "muted" });
    // The rig's pace and the turn's length (rig/pace.js).
    this.pace = h("p", { class: "muted", "data-testid": "rig-pace" });
    this.banner = h("p", { class: "error", role: "alert", "data-testid": "rig-error" });
    this.title = h("span", { "data-testid": "rig-title" }, rigId);
    main.append(
      h("p", { class: "crumbs" }, h("a", { href: "#/" }, t("nav.rigs")), t("crumbs.separator"), rigId),
      h("h1", null, this.title, " ", this.badge),
      h("p", null, this.detail),
      this.pace,
      this.banner,
    );
  }

  setTitle(title) {
    setText(this.title, rigTitle({ id: title, title }));
  }

  /** @param {string} text */
  setPace(text) {
    setText(this.pace, text);
  }

  /** Show the rig's state; a change to a fault is also said aloud. */
  setState(state, detail) {
    const before = this.state;
    this.state = state;
    setText(this.badge, stateLabel(state));
    this.badge.dataset.state = state;
    setText(this.detail, detail ?? "");
    if (before && before !== state && (state === "fault" || state === "out_of_service")) {
      announce(t(detail ? "rig.stateChangedWhy" : "rig.stateChanged", { rig: this.rigId, state: stateLabel(state), detail }), "alert");
    }
  }

  error(message) {
    setText(this.banner, message);
    clearTimeout(this._bannerTimer);
    this._bannerTimer = setTimeout(() => setText(this.banner, ""), BANNER_MS);
  }

  destroy() {
    clearTimeout(this._bannerTimer);
  }
}
