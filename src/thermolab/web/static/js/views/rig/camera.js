// @ts-check
// The rig's live image: one JPEG a second over HTTP while the tab is visible.

import { api } from "../../api.js";
import { h, setText } from "../../dom.js";
import { t } from "../../i18n.js";

const CAMERA_MS = 1000;

export class Camera {
  /**
   * @param {HTMLElement} parent
   * @param {string} rigId
   */
  constructor(parent, rigId) {
    this.rigId = rigId;
    this._destroyed = false;
    this._timer = 0;
    /** The one object URL alive (each holds its image until revoked). */
    this._url = null;
    this.img = h("img", { class: "camera", alt: t("camera.alt", { rig: rigId }), width: "320", height: "240", hidden: true });
    this.note = h("p", { class: "muted small" }, t("camera.none"));
    parent.append(
      h(
        "section",
        { class: "card", "aria-labelledby": "camera-heading" },
        h("h2", { id: "camera-heading" }, t("camera.heading")),
        h("div", { class: "camera-box" }, this.img, this.note),
      ),
    );
    void this._load();
  }

  _next() {
    this._timer = setTimeout(() => void this._load(), CAMERA_MS);
  }

  async _load() {
    if (this._destroyed) return;
    if (document.hidden) return this._next();
    try {
      const res = await fetch(api.cameraUrl(this.rigId), { cache: "no-store", credentials: "same-origin" });
      if (!res.ok) throw new Error(`${res.status}`);
      const blob = await res.blob();
      if (this._destroyed) return;
      const url = URL.createObjectURL(blob);
      this.img.src = url;
      this.img.hidden = false;
      if (this._url) URL.revokeObjectURL(this._url);
      this._url = url;
      setText(this.note, "");
    } catch {
      this.img.hidden = true;
      setText(this.note, t("camera.unavailable"));
    }
    this._next();
  }

  destroy() {
    this._destroyed = true;
    clearTimeout(this._timer);
    if (this._url) URL.revokeObjectURL(this._url);
    this._url = null;
  }
}
