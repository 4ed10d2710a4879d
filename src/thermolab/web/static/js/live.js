// @ts-check
// The live WebSocket client (contract: docs/live-protocol.md).
//
// One LiveClient per rig page. It reconnects by itself with exponential
// backoff and jitter, resumes with `since=<last seq>` so the server replays the
// gap, drops anything it has already seen (a replay may overlap), keeps the
// controller's presence alive with pings, and treats a silent connection as
// dead (a half-open TCP connection after a network drop never says "closed").

import { t } from "./i18n.js";

/** Close codes of the protocol that mean "do not come back". */
export const CLOSE_UNAUTHORIZED = 4401;
export const CLOSE_UNKNOWN_RIG = 4404;
export const CLOSE_TOO_SLOW = 4408;

/**
 * Delay before reconnection attempt `attempt` (0-based): exponential growth
 * capped at `maxMs`, with "equal jitter" (half fixed, half random) so that a
 * classroom of clients dropped by one server restart does not come back in
 * lockstep, while no client waits less than half the nominal delay.
 * @param {number} attempt
 * @param {{baseMs?: number, maxMs?: number, random?: () => number}} [opts]
 */
export function backoffDelay(attempt, { baseMs = 500, maxMs = 15000, random = Math.random } = {}) {
  const nominal = Math.min(maxMs, baseMs * 2 ** Math.min(attempt, 30));
  return nominal / 2 + random() * (nominal / 2);
}

/**
 * The WebSocket URL of a rig's live stream, relative to the page's origin.
 * @param {string} rig
 * @param {number | null} since
 * @param {Location | URL} [where]
 */
export function liveUrl(rig, since, where = window.location) {
  const scheme = where.protocol === "https:" ? "wss:" : "ws:";
  const query = since === null || since === undefined ? "" : `?since=${encodeURIComponent(since)}`;
  return `${scheme}//${where.host}/api/rigs/${encodeURIComponent(rig)}/live${query}`;
}

export class LiveClient {
  /**
   * @param {string} rig
   * @param {object} handlers
   * @param {(msg: object) => void} handlers.onMessage every new message, in order, with
   *   `samples` batches already split into `sample` messages
   * @param {(status: {state: string, attempt: number, delayMs?: number, code?: number,
   *   reason?: string}) => void} [handlers.onStatus] connection state changes:
   *   `connecting`, `open`, `waiting` (before a retry), `closed` (given up)
   * @param {object} [options]
   * @param {typeof WebSocket} [options.WebSocketImpl]
   * @param {(rig: string, since: number | null) => string} [options.url]
   * @param {number} [options.pingMs] interval between pings (presence)
   * @param {number} [options.silenceMs] no message for this long means the link is dead
   * @param {() => number} [options.random]
   * @param {{setTimeout: Function, clearTimeout: Function}} [options.timers]
   * @param {() => number} [options.now]
   * @param {number} [options.baseMs] first reconnection delay
   * @param {number} [options.maxMs] longest reconnection delay
   */
  constructor(rig, { onMessage, onStatus = () => {} }, options = {}) {
    this.rig = rig;
    this._onMessage = onMessage;
    this._onStatus = onStatus;
    this._WS = options.WebSocketImpl ?? globalThis.WebSocket;
    this._url = options.url ?? ((r, s) => liveUrl(r, s));
    this._pingMs = options.pingMs ?? 5000;
    this._silenceMs = options.silenceMs ?? 3 * this._pingMs;
    this._random = options.random ?? Math.random;
    this._timers = options.timers ?? globalThis;
    this._now = options.now ?? (() => Date.now());
    this._backoff = { baseMs: options.baseMs ?? 500, maxMs: options.maxMs ?? 15000 };
    /** The seq of the newest stream message delivered; null before the first. */
    this.lastSeq = null;
    this.attempt = 0;
    this.state = "idle";
    this._ws = null;
    this._retryTimer = null;
    this._pingTimer = null;
    this._lastHeard = 0;
    this._stopped = false;
    this._historyPending = false;
    this._historyUpTo = null;
  }

  start() {
    this._stopped = false;
    this._connect();
  }

  /** Close for good (leaving the page): no reconnection, no timers left behind. */
  stop() {
    this._stopped = true;
    this._clearTimers();
    if (this._ws) {
      const ws = this._ws;
      this._ws = null;
      ws.onopen = ws.onmessage = ws.onerror = ws.onclose = null;
      try {
        ws.close(1000, "leaving");
      } catch {
        // already closing
      }
    }
    this._setState("closed", {});
  }

  /**
   * Reconnect at once asking for everything the server still holds
   * (`since=0`): a page that joins a run half-way gets the run's samples
   * (from the store) and the recent estimates. Messages up to the new hello's
   * `seq`, and stored samples (which carry no `seq`), are delivered with
   * `history: true`.
   */
  replayAll() {
    if (this._stopped) return;
    this._clearTimers();
    if (this._ws) {
      const ws = this._ws;
      this._ws = null;
      ws.onopen = ws.onmessage = ws.onerror = ws.onclose = null;
      try {
        ws.close(1000, "replay");
      } catch {
        // already closing
      }
    }
    this.lastSeq = 0;
    this._historyPending = true;
    this._historyUpTo = null;
    this.attempt = 0;
    this._connect();
  }

  /** Reconnect now (the browser says it is back online): skip the backoff wait. */
  reconnectNow() {
    if (this._stopped || this.state === "open" || this.state === "connecting") return;
    this.attempt = 0;
    this._clearTimers();
    this._connect();
  }

  _setState(state, extra) {
    this.state = state;
    this._onStatus({ state, attempt: this.attempt, ...extra });
  }

  _clearTimers() {
    if (this._retryTimer !== null) this._timers.clearTimeout(this._retryTimer);
    if (this._pingTimer !== null) this._timers.clearTimeout(this._pingTimer);
    this._retryTimer = null;
    this._pingTimer = null;
  }

  _connect() {
    this._retryTimer = null;
    this._setState("connecting", {});
    let ws;
    try {
      ws = new this._WS(this._url(this.rig, this.lastSeq));
    } catch (err) {
      this._scheduleRetry({ code: 0, reason: String(err) });
      return;
    }
    this._ws = ws;
    ws.onopen = () => {
      this._lastHeard = this._now();
      this._setState("open", {});
      this._schedulePing();
    };
    ws.onmessage = (ev) => {
      this._lastHeard = this._now();
      let msg;
      try {
        msg = JSON.parse(ev.data);
      } catch {
        return; // not ours to interpret; the protocol only sends JSON
      }
      // A frame holds one message, or an array of them in order (a backlog sent at once).
      for (const one of Array.isArray(msg) ? msg : [msg]) {
        if (one && typeof one === "object") this._deliver(one);
      }
    };
    ws.onclose = (ev) => {
      if (this._ws !== ws) return;
      this._ws = null;
      this._clearTimers();
      if (this._stopped) return;
      if (ev.code === CLOSE_UNAUTHORIZED || ev.code === CLOSE_UNKNOWN_RIG) {
        this._stopped = true;
        this._setState("closed", { code: ev.code, reason: ev.reason });
        return;
      }
      this._scheduleRetry({ code: ev.code, reason: ev.reason });
    };
    ws.onerror = () => {
      // A close event always follows; reconnection is decided there.
    };
  }

  _scheduleRetry(info) {
    // "Too slow" is the server shedding load, not a failure of ours: come back
    // soon, but still with jitter.
    const attempt = info.code === CLOSE_TOO_SLOW ? 0 : this.attempt;
    const delayMs = backoffDelay(attempt, { ...this._backoff, random: this._random });
    this.attempt += 1;
    this._setState("waiting", { delayMs, ...info });
    this._retryTimer = this._timers.setTimeout(() => this._connect(), delayMs);
  }

  _schedulePing() {
    this._pingTimer = this._timers.setTimeout(() => {
      this._pingTimer = null;
      const ws = this._ws;
      if (!ws) return;
      if (this._now() - this._lastHeard > this._silenceMs) {
        // Dead link: close it ourselves; onclose (or the fallback below) reconnects.
        this._ws = null;
        ws.onopen = ws.onmessage = ws.onerror = ws.onclose = null;
        try {
          ws.close(4000, "silent");
        } catch {
          // ignore
        }
        this._scheduleRetry({ code: 4000, reason: t("live.silent") });
        return;
      }
      try {
        ws.send(JSON.stringify({ type: "ping" }));
      } catch {
        // the close event will follow
      }
      this._schedulePing();
    }, this._pingMs);
  }

  _deliver(msg) {
    if (msg.type === "hello") {
      // A hello means the server accepted us: the next failure starts the backoff afresh.
      this.attempt = 0;
      // A first connection has no history: start counting from the server's present. A
      // server below our last number (its clock was set back across a restart) numbers
      // afresh: count from its present too, or everything new would look already seen.
      if (typeof msg.seq === "number" && (this.lastSeq === null || msg.seq < this.lastSeq)) {
        this.lastSeq = msg.seq;
      }
      if (this._historyPending) {
        this._historyPending = false;
        this._historyUpTo = typeof msg.seq === "number" ? msg.seq : null;
      }
      this._onMessage(msg);
      return;
    }
    const history = (seq) => this._historyUpTo !== null && (typeof seq !== "number" || seq <= this._historyUpTo);
    if (typeof msg.seq === "number" && this._historyUpTo !== null && msg.seq > this._historyUpTo) {
      this._historyUpTo = null; // live from here on
    }
    if (msg.type === "samples" && Array.isArray(msg.items)) {
      for (const item of msg.items) {
        if (typeof item.seq === "number") {
          if (this.lastSeq !== null && item.seq <= this.lastSeq) continue;
          this.lastSeq = item.seq;
        }
        this._onMessage({ type: "sample", ...item, history: history(item.seq) });
      }
      if (typeof msg.seq === "number" && (this.lastSeq === null || msg.seq > this.lastSeq)) {
        this.lastSeq = msg.seq;
      }
      return;
    }
    if (typeof msg.seq === "number") {
      if (this.lastSeq !== null && msg.seq <= this.lastSeq) return; // replay overlap
      this.lastSeq = msg.seq;
    }
    if (history(msg.seq) && msg.type !== "access" && msg.type !== "state") msg.history = true;
    this._onMessage(msg);
  }
}
