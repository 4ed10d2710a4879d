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

/**
 * One end of a run's identified pair for people: a further channel by its words,
 * u and y as a kit's heater 1 and sensor 1 on a kit, else as the input and output.
 * @param {string} name  "u", "y" or a further channel's name
 * @param {boolean} kit  whether the rig is a kit (it declares heater 2)
 */
export function pairEnd(name, kit) {
  if (name === "u") return kit ? t("channel.q1") : t("channel.u");
  if (name === "y") return kit ? t("channel.t1") : t("channel.y");
  return channelName(name);
}

/**
 * Whether a pair is a kit's (either end heater 2 or sensor 2): its u and y are then heater 1 and sensor 1.
 * @param {string} input
 * @param {string} output
 */
export function kitPair(input, output) {
  return [input, output].some((n) => n === "q2" || n === "t2");
}

/**
 * A pair's words ("Heater 2, Q2 → Temperature 2, T2"), the rig a kit when either end is q2 or t2.
 * @param {string} input
 * @param {string} output
 * @param {boolean} [kit]
 */
export function pairLabel(input, output, kit = kitPair(input, output)) {
  return t("panel.pairOption", { input: pairEnd(input, kit), output: pairEnd(output, kit) });
}

/**
 * The input/output pairs a run on the rig may identify (RunIn.input, RunIn.output):
 * its input u or a further input it records, by its output y or a further output,
 * the standard pair first (thermolab.runner.pair). One pair only for a rig without
 * further channels.
 * @param {{actuators: {name: string, unit: string, recorded: boolean}[],
 *   outputs: {name: string, unit: string}[]}} rig
 * @returns {{input: string, output: string, label: string}[]}
 */
export function pairChoices(rig) {
  const kit = rig.actuators.some((a) => a.name === "q2");
  const inputs = ["u", ...rig.actuators.filter((a) => a.recorded).map((a) => a.name)];
  const outputs = ["y", ...rig.outputs.map((o) => o.name)];
  return inputs.flatMap((input) => outputs.map((output) => ({ input, output, label: pairLabel(input, output, kit) })));
}
