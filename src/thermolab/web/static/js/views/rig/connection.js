// @ts-check
// The connection line (#conn) of the rig page: what the live socket is doing.

import { setText } from "../../dom.js";
import { t } from "../../i18n.js";

/** How long "Connected again." stays up. */
const RECONNECTED_MS = 2000;

/**
 * Show a LiveClient status change.
 * @param {{state: string, delayMs?: number, code?: number}} s
 * @param {() => boolean} isOpen  whether the socket is (still) open
 * @param {() => void} onNoSuchRig  the server closed the socket: there is no such rig
 */
export function showConnection(s, isOpen, onNoSuchRig) {
  const conn = document.getElementById("conn");
  if (!conn) return;
  if (s.state === "open") {
    if (conn.textContent) setText(conn, t("conn.again"));
    setTimeout(() => {
      if (isOpen()) setText(conn, "");
    }, RECONNECTED_MS);
  } else if (s.state === "waiting") {
    const seconds = Math.ceil((s.delayMs ?? 0) / 1000);
    setText(conn, t("conn.waiting", { seconds }));
  } else if (s.state === "closed" && s.code) {
    setText(conn, "");
    if (s.code === 4404) onNoSuchRig();
  }
}

/** Clear the connection line (leaving the page). */
export function clearConnection() {
  const conn = document.getElementById("conn");
  if (conn) setText(conn, "");
}
