// @ts-check
// How fast the rig runs and how long a turn lasts, in one sentence under the
// rig's name: a twin at 1x takes the paper's first experiment 33 minutes, and a
// newcomer who is not told thinks the lab is stuck (issue #24).

import { durationWords } from "../../dom.js";
import { formatNumber, t } from "../../i18n.js";

/** The paper's first experiment: 2000 samples at T = 1 s (a step from 0 to 10 V). */
export const PAPER_EXPERIMENT_SECONDS = 2000;

/**
 * The pace and the turn, as the page says them ("" when neither is known).
 * @param {{kind: string, speedup: number | null, limits: Record<string, unknown>}} rig
 * @returns {string}
 */
export function paceText(rig) {
  const seconds = formatNumber(PAPER_EXPERIMENT_SECONDS);
  const parts = [];
  const speedup = rig.speedup;
  if (rig.kind !== "sim") {
    parts.push(t("rig.paceHardware", { seconds, wall: durationWords(PAPER_EXPERIMENT_SECONDS) }));
  } else if (speedup !== null && speedup > 0) {
    const wall = durationWords(PAPER_EXPERIMENT_SECONDS / speedup);
    parts.push(
      speedup === 1
        ? t("rig.paceRealTime", { seconds, wall })
        : t("rig.paceTwin", { speedup: formatNumber(speedup, { maximumFractionDigits: 2 }), seconds, wall }),
    );
  }
  const turn = rig.limits.controlTimeLimit;
  if (typeof turn === "number" && Number.isFinite(turn)) parts.push(t("rig.turnLasts", { turn: durationWords(turn) }));
  return parts.join(" ");
}
