// @ts-check
// A rig's further channels, besides its input u and output y, in the reader's
// words: by the names the rig declares them under (a kit's heater 2 `q2` and
// sensor 2 `t2`, a twin's fan). The "Now" card, the live charts and the
// control of a further input all name a channel here; one the catalogue has
// no words for is shown by its name.

import { t } from "./i18n.js";
import { unitSymbol } from "./quantities.js";

/** @type {Readonly<Record<string, string>>} The words for each further channel a rig's kind declares, by its name. */
const CHANNEL_NAMES = Object.freeze({ fan: "channel.fan", q2: "channel.q2", t2: "channel.t2" });

/**
 * A further channel's name for people ("Heater 2, Q2").
 * @param {string} name  as the rig declares it
 * @returns {string}
 */
export function channelName(name) {
  return name in CHANNEL_NAMES ? t(CHANNEL_NAMES[name]) : name;
}

/**
 * A further channel's name with its unit ("Temperature 2, T2 (°C)").
 * @param {string} name  as the rig declares it
 * @param {string} unit  as the rig declares it ("degC" reads "°C")
 * @returns {string}
 */
export function channelLabel(name, unit) {
  return unit ? t("channel.withUnit", { name: channelName(name), unit: unitSymbol(unit) }) : channelName(name);
}
