// @ts-check
// A run described for people, in the reader's language: its input signal
// ("step from 0 to 10 V at t = 1 s" rather than "step:0:10@1"), why it ended
// and its method settings ("Window: 40" rather than "window = 40"). The
// signal grammar is the server's (thermolab.signals: const:U, step:U0:U1@T,
// square:LOW:HIGH:FREQ_HZ, sine:OFFSET:AMPLITUDE:FREQ_HZ,
// prbs:LOW:HIGH:BIT_SECONDS[:SEED]); a spec this page cannot read is shown as sent.

import { h, serverText, tParts } from "./dom.js";
import { formatDecimal, t } from "./i18n.js";
import { formatQuantity } from "./quantities.js";

/**
 * A signal specification in words, or null when it is not one this page knows.
 * @param {string} spec
 * @param {string} [unit]  the input's unit (volts on the paper's box)
 * @returns {string | null}
 *
 * @example signalText("step:0:10@1") // "step from 0 to 10 V at t = 1 s"; pt-BR "degrau de 0 a 10 V em t = 1 s"
 */
export function signalText(spec, unit = "V") {
  const text = String(spec).trim();
  const [kindPart, ...rest] = text.split(":");
  const kind = kindPart.trim().toLowerCase();
  const joined = rest.join(":");
  const fields = (kind === "step" ? joined.replace("@", ":") : joined).split(":").map((f) => Number(f.trim()));
  if (rest.length === 0 || fields.some((f) => !Number.isFinite(f))) return null;
  const v = (x) => formatQuantity(x, "volts");
  const s = (x) => formatQuantity(x, "seconds");
  const [a, b, c] = fields;
  if (kind === "const" && fields.length === 1) return t("signal.const", { level: v(a), unit });
  if (kind === "step" && fields.length === 3) return t("signal.step", { from: v(a), to: v(b), at: s(c), unit });
  if (kind === "square" && fields.length === 3 && c > 0) {
    return t("signal.square", { low: v(a), high: v(b), period: s(1 / c), unit });
  }
  if (kind === "sine" && fields.length === 3 && c > 0) {
    return t("signal.sine", { offset: v(a), amplitude: v(b), period: s(1 / c), unit });
  }
  if (kind === "prbs" && (fields.length === 3 || fields.length === 4)) return t("signal.prbs", { low: v(a), high: v(b), bit: s(c), unit });
  return null;
}

/**
 * What drove a run's input: its signal in words, the manual set point, or "manual".
 * @param {{signal: string | null, setpoint: number | null}} run
 */
export function inputText(run) {
  if (run.signal) return signalText(run.signal) ?? run.signal;
  if (run.setpoint !== null && run.setpoint !== undefined) return t("run.inputManualSetpoint", { setpoint: formatQuantity(run.setpoint, "volts") });
  return t("run.inputManual");
}

/** The words for the runner's end reasons (thermolab.runner.state.EndReason) and the lab's own. */
const END_REASONS = {
  ended: "runEnd.ended",
  interlock: "runEnd.interlock",
  rig_fault: "runEnd.rigFault",
  watchdog: "runEnd.watchdog",
  error: "runEnd.error",
  aborted: "runEnd.aborted",
  // A rig host's run that ended for want of the lab (lab/runs/ending.py, EndCause).
  link_lost: "runEnd.linkLost",
  host_away: "runEnd.hostAway",
  owner_gone: "runEnd.ownerGone",
};

/**
 * Why a run ended (RunOut.endReason: "completed", "ended by ana",
 * "interlock: output over 11 V", "the server stopped"), in the reader's
 * language: `text` the words, `detail` the server's own English explanation
 * after the reason's code (null when none; shown marked as English).
 * Null when the reason adds nothing to the run's status ("completed").
 * @param {string | null | undefined} reason
 * @returns {{text: string, detail: string | null} | null}
 */
export function endReasonText(reason) {
  if (!reason) return null;
  const words = String(reason);
  if (words === "completed") return null; // "finished" already says it
  const endedBy = /^ended by (.+)$/.exec(words);
  if (endedBy) return { text: t("runEnd.endedBy", { user: endedBy[1] }), detail: null };
  if (words in END_REASONS) return { text: t(END_REASONS[words]), detail: null };
  // The lab's own words for a run its server stopped (lab/runs/ending.py, lab/access/queries.py).
  if (words.startsWith("the server stopped")) return { text: t("runEnd.serverStopped"), detail: null };
  const colon = words.indexOf(":");
  const code = colon > 0 ? words.slice(0, colon) : "";
  if (code in END_REASONS) return { text: t(END_REASONS[code]), detail: words.slice(colon + 1).trim() || null };
  return { text: "", detail: words };
}

/** The labels of a run's method settings (RunOut.settings), by name. */
const SETTING_LABELS = {
  window: "setting.window",
  block: "setting.block",
  gamma: "setting.gamma",
  pmax: "setting.pmax",
};
/** Settings shown elsewhere on the run's page (sample time, samples, input, methods, W0, operating point). */
// The pair identified (input, output) is said on its own where it is not u -> y (channelwords.pairLabel).
const SHOWN_ELSEWHERE = new Set(["dt", "samples", "signal", "setpoint", "methods", "w0", "offset", "input", "output"]);

/**
 * A run's method settings as "label: value" pieces in the reader's language,
 * those with no value and those shown elsewhere left out.
 * @param {Record<string, unknown>} settings
 * @returns {string[]}
 */
export function settingsText(settings) {
  const pieces = [];
  for (const [name, value] of Object.entries(settings ?? {})) {
    if (SHOWN_ELSEWHERE.has(name) || value === null || value === undefined || typeof value === "object") continue;
    const label = name in SETTING_LABELS ? t(SETTING_LABELS[name]) : name;
    let shown;
    if (typeof value === "number") shown = Number.isInteger(value) ? String(value) : formatDecimal(Number(value.toPrecision(6)));
    else shown = String(value);
    if (name === "block" && value === 0) shown = t("setting.blockNone");
    pieces.push(t("setting.piece", { label, value: shown }));
  }
  return pieces;
}

/**
 * Why a run ended, for a message's {reason}: the words, with the server's
 * English explanation marked as English; null when there is nothing to add.
 * @param {string | null | undefined} reason
 * @returns {Node | string | null}
 */
export function endReasonNode(reason) {
  const why = endReasonText(reason);
  if (!why) return null;
  if (!why.detail) return why.text;
  if (!why.text) return serverText(why.detail);
  return h("span", null, why.text, ": ", serverText(why.detail));
}

/**
 * A run's status with why it ended ("concluído", "encerrado (encerrado por ana)").
 * @param {{status: string, endReason: string | null}} run
 * @param {(status: string) => string} statusText  the words of a status (runspec.js runStatusText)
 * @returns {Array<Node | string>}
 */
export function statusParts(run, statusText) {
  const reason = endReasonNode(run.endReason);
  const status = statusText(run.status);
  return reason === null ? [status] : tParts("runs.statusWhy", { status, reason });
}
