// @ts-check
// "Your next chance" on the rig page: whether a course's slot holds the rig now
// (the reader's own course, named, or another, only as reserved), when the
// reader may ask for control again, and their course's next slot. The server
// works it out from the bookings (GET /api/rigs/{rig}/next-chance); the times
// are shown in the reader's zone and language.

import { api } from "../../api.js";
import { h, setText } from "../../dom.js";
import { formatDateTime, t } from "../../i18n.js";

/** How often the line is read again (a slot may begin while the page is open). */
const REFRESH_MS = 30000;

/** @param {string} iso */
function at(iso) {
  return formatDateTime(new Date(iso), { dateStyle: "medium", timeStyle: "short" });
}

export class NextChance {
  /**
   * @param {HTMLElement} parent
   * @param {string} rigId
   */
  constructor(parent, rigId) {
    this.rigId = rigId;
    this.now = h("span", { "data-testid": "chance-now" });
    this.next = h("span", { "data-testid": "chance-next" });
    this.el = h(
      "p",
      { class: "chance", "data-testid": "next-chance" },
      this.now,
      " ",
      this.next,
      " ",
      h("a", { href: "#/bookings" }, t("chance.calendar")),
    );
    parent.append(this.el);
    this._timer = setInterval(() => void this.refresh(), REFRESH_MS);
    void this.refresh();
  }

  async refresh() {
    let chance;
    try {
      chance = await api.nextChance(this.rigId);
    } catch {
      return; // the page says elsewhere when the lab cannot be reached
    }
    const booked = chance?.bookedNow;
    if (!booked) setText(this.now, t("chance.free"));
    else if (booked.own) setText(this.now, t("chance.ownNow", { course: booked.courseTitle ?? booked.course ?? "", end: at(booked.endsAt) }));
    else setText(this.now, t("chance.otherNow", { end: at(booked.endsAt), free: at(chance.freeFrom ?? booked.endsAt) }));
    const mine = chance?.nextOwn;
    setText(this.next, mine ? t("chance.nextOwn", { start: at(mine.startsAt), end: at(mine.endsAt) }) : "");
  }

  destroy() {
    clearInterval(this._timer);
  }
}
