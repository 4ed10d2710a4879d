// @ts-check
// What happened to my turn and my run, said on the page and kept there (WCAG
// 4.1.3: a status message in a polite live region, role="status"): a teacher
// ended my turn, my time ran out, the server restarted and interrupted my run.
// The reason comes from the server's record of my last turn
// (GET /api/rigs/{rig}/control-sessions), never guessed from the socket.

import { api } from "../../api.js";
import { h, setText } from "../../dom.js";
import { t } from "../../i18n.js";

/** The message of each way a turn ends (released: the student did it, nothing to say). */
const ENDED = {
  kicked: "turn.endedKicked",
  time_limit: "turn.endedTime",
  idle: "turn.endedIdle",
  client_gone: "turn.endedGone",
  rig_fault: "turn.endedFault",
  server_restart: "turn.endedRestart",
  booked: "turn.endedBooked",
};

export class TurnNotice {
  /**
   * @param {HTMLElement} parent
   * @param {string} rigId
   */
  constructor(parent, rigId) {
    this.rigId = rigId;
    /** @type {string[]} */
    this.lines = [];
    // h() sets `hidden` as a property: "" would be false and leave an empty bar on the page.
    this.el = h("p", { class: "notice", role: "status", "data-testid": "turn-notice", hidden: true });
    parent.append(this.el);
  }

  /** Say why my turn ended (the newest of my turns, as the server stored it). */
  async turnEnded() {
    let turns;
    try {
      turns = await api.controlSessions(this.rigId);
    } catch {
      return;
    }
    const last = Array.isArray(turns) ? turns[0] : null;
    const key = last && typeof last.endReason === "string" ? ENDED[last.endReason] : undefined;
    if (key) this.add(t(key, { by: last.endedBy ?? "" }));
  }

  /** Say what became of a run that was going when the connection went. */
  async runAfterOutage(runId) {
    let run;
    try {
      run = await api.run(runId);
    } catch {
      return;
    }
    if (run && run.status === "interrupted") this.add(t("turn.runInterrupted", { run: runId }));
  }

  /** @param {string} line */
  add(line) {
    if (this.lines.includes(line)) return;
    this.lines.push(line);
    setText(this.el, this.lines.join(" "));
    this.el.hidden = false;
  }

  /** A new turn: the old news goes. */
  clear() {
    this.lines = [];
    setText(this.el, "");
    this.el.hidden = true;
  }
}
