// @ts-check
// Why the panels are locked for this user now ("" when they may use them).

import { t } from "../../i18n.js";

/**
 * @param {{role: string, queuePosition: number | null} | null} access  this user's access (null: not known yet)
 * @param {string | undefined} state  the rig's state
 * @returns {string}
 */
export function lockReason(access, state) {
  if (!access) return t("lock.connecting");
  if (state === "out_of_service") return t("lock.outOfService");
  if (state === "fault") return t("lock.fault");
  if (access.role === "controller") return "";
  return access.role === "queued" || access.queuePosition
    ? t("lock.queued", { position: access.queuePosition })
    : t("lock.watching");
}

/**
 * Whether the lock's reason only repeats the access card's role (watching, queued): on a
 * phone the card sits right above the panels, and the css leaves this copy out there.
 * @param {{role: string, queuePosition: number | null} | null} access
 * @param {string | undefined} state
 * @returns {boolean}
 */
export function lockRepeatsRole(access, state) {
  return Boolean(access) && state !== "out_of_service" && state !== "fault" && access?.role !== "controller";
}
