// @ts-check
// Whether the lab answers, for the rig page. When the live socket drops the page
// asks over HTTP at once; if the server does not answer either, the page says
// so, shows no role or countdown and locks the controls until an answer comes
// back, and then says what became of the run that was going (interrupted by a
// restart; the turn's end is told by rig/notice.js from the stored reason).

import { announce } from "../../dom.js";
import { t } from "../../i18n.js";

export class Reachability {
  /**
   * @param {{access: any, client: any, notice: any, currentRun: () => any, poll: () => void, updateLock: () => void}} page
   */
  constructor(page) {
    this.page = page;
    /** Whether the lab answers (HTTP or socket); false locks everything. */
    this.reachable = true;
    /** The run that was going when the lab stopped answering (its fate is told after). */
    this._runAtOutage = null;
  }

  /**
   * A status of the live socket; returns whether the connection line should show it
   * (not while it says the lab cannot be reached).
   * @param {{state: string}} s
   */
  status(s) {
    if (s.state === "open") this.set(true);
    else if (s.state === "waiting" && this.reachable) this.page.poll(); // the socket, or the lab?
    return this.reachable || s.state !== "waiting";
  }

  /** The lab answers again (true), or stopped answering (false): say so, lock or unlock. */
  set(reachable) {
    if (reachable === this.reachable) return;
    this.reachable = reachable;
    const { access, client, notice } = this.page;
    if (!reachable) {
      const run = this.page.currentRun();
      this._runAtOutage = run?.status === "running" ? run.id : null;
      access.setUnreachable(true);
      const conn = document.getElementById("conn");
      if (conn) conn.textContent = t("turn.connLost");
      announce(t("turn.connLost"), "alert");
    } else {
      // The line keeps saying so until the socket is back ("Connected again.").
      access.setUnreachable(false);
      client.reconnectNow();
      const run = this._runAtOutage;
      this._runAtOutage = null;
      if (run !== null) void notice.runAfterOutage(run);
    }
    this.page.updateLock();
  }
}
