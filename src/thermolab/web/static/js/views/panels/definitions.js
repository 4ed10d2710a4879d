// @ts-check
// What each of the paper's three panels asks for (section II, Figs. 6–8): its
// fields with their defaults and allowed ranges, the methods it runs and the
// operating-point modes it offers. The ranges come from the rig (the input)
// and the server's schema (the run settings); the defaults until they are known
// are conservative, and the panels stay locked until then anyway.

import { panelMethods, settingRange } from "../../methods.js";
import { enumValues, hasProperty, numericRange } from "../../schema.js";
import { t } from "../../i18n.js";
import { unitSymbol } from "../../quantities.js";
import { pairChoices } from "../../channelwords.js";

/**
 * @typedef {import("../../validate.js").FieldSpec & {name: string, value: number | string,
 *   hint?: string, step?: string, automaticOnly?: boolean, manualOnly?: boolean,
 *   plannedOnly?: boolean}} FieldDef
 */

/**
 * The run's own settings: conservative ranges used until the server's (from
 * /openapi.json) are known; the panels are locked until then anyway.
 */
export const RUN_RANGES = Object.freeze({
  dt: { min: 0.01, max: 3600 },
  samples: { min: 1, max: 200000, integer: true },
});

/**
 * A method setting's range and default (methods.js), without its default.
 * @param {string} method
 * @param {string} setting
 */
function methodRange(method, setting) {
  const { value, ...range } = settingRange(method, setting);
  return range;
}

/**
 * A method setting's default, as a form field's starting value.
 * @param {string} method
 * @param {string} setting
 * @returns {number}
 */
function defaultOf(method, setting) {
  return Number(settingRange(method, setting).value);
}

/** The ranges of every setting a panel shows, before the server's schema is known. */
export function defaultRanges() {
  return {
    ...RUN_RANGES,
    window: methodRange("malsm", "window"),
    block: methodRange("blockls", "block"),
    gamma: methodRange("wlsm", "gamma"),
    pmax: methodRange("wlsm", "pmax"),
  };
}

/** The choices of RunIn.offset, as the select shows them (OFFSET_HINT says what they mean). */
export const OFFSET_LABELS = Object.freeze({
  auto: "offset.auto",
  initial: "offset.initial",
  fit: "offset.fit",
  none: "offset.none",
});
/** What the operating-point modes mean (the hint under the select). */
export const OFFSET_HINT = "offset.hint";

/**
 * What the panels may accept: the rig's published input range, and the run
 * settings' ranges from the server's own schema (RunIn in /openapi.json).
 * @param {{inputMin: number, inputMax: number, inputUnit: string,
 *   actuators: {name: string, unit: string, recorded: boolean}[],
 *   outputs: {name: string, unit: string}[]} | null} rig
 * @param {any} doc  the server's OpenAPI document, or null while unknown
 */
export function panelLimits(rig, doc) {
  const ranges = {};
  for (const field of ["dt", "samples", "window", "block", "gamma", "pmax"]) {
    const r = doc ? numericRange(doc, "RunIn", field) : null;
    if (r) ranges[field] = r;
  }
  return {
    inputMin: rig ? rig.inputMin : -10,
    inputMax: rig ? rig.inputMax : 10,
    inputUnit: rig?.inputUnit ?? "V",
    ranges,
    w0: Boolean(doc && hasProperty(doc, "RunIn", "w0")),
    offsets: doc ? enumValues(doc, "RunIn", "offset") : null,
    // The pairs a run may identify, when the server takes a pair (a kit: Q1/Q2 by T1/T2).
    pairs: rig && doc && hasProperty(doc, "RunIn", "input") ? pairChoices(rig) : [],
  };
}

/**
 * Field definitions of each panel.
 * @param {{inputMin: number, inputMax: number, inputUnit: string,
 *   ranges: Record<string, any>, w0: boolean, offsets?: string[] | null}} limits  the
 *   rig's input range, the server's ranges for the run's settings, whether it takes
 *   initial WLSM parameters, and the operating-point modes it offers (null: none)
 */
export function panelDefinitions(limits) {
  /** @type {Record<string, any>} */
  const r = { ...defaultRanges(), ...limits.ranges };
  const w0 = /** @type {number[]} */ (settingRange("wlsm", "w0").value ?? [Number.NaN, Number.NaN]);
  const u = { min: limits.inputMin, max: limits.inputMax, unit: unitSymbol(limits.inputUnit) };
  const common = [
    { name: "dt", label: t("field.dt"), ...r.dt, unit: "s", value: 1 },
    { name: "n", label: t("field.samples"), ...r.samples, integer: true, value: 2000 },
  ];
  const setpoint = (value) => ({ name: "setpoint", label: t("field.setpoint"), ...u, value, manualOnly: true });
  const auto = (lo, hi) => [
    { name: "low", label: t("field.low"), ...u, value: lo, automaticOnly: true },
    { name: "high", label: t("field.high"), ...u, value: hi, automaticOnly: true },
  ];
  // γ < 1 (the paper's form) is the lab's narrowing, published in /api/methods' runSettings.
  const gamma = r.gamma;
  const w0Note = limits.w0
    ? null
    : t("field.w0Unavailable");
  return [
    {
      id: "srm-lsm",
      number: 1,
      title: t("panel.srmLsm.title"),
      short: t("panel.srmLsm.tab"),
      intro: t("panel.srmLsm.intro"),
      fields: [
        ...common,
        // 0 is "off"; otherwise the server's block range (checked in checkPanel).
        { name: "block", label: t("field.block"), min: 0, max: r.block.max, integer: true, unit: t("unit.samples"), value: 0, blockMin: r.block.min },
        setpoint(0),
        // The planned step (the set point changed at a chosen time): at a twin's
        // speed-up a change made by hand lands on no sample one can choose.
        { name: "stepTo", label: t("field.stepTo"), ...u, value: 10, manualOnly: true, plannedOnly: true },
        { name: "stepAt", label: t("field.stepAt"), min: 0, max: r.dt.max * r.samples.max, unit: "s", value: 1, manualOnly: true, plannedOnly: true },
        ...auto(4, 6),
      ],
      methods: panelMethods("srm-lsm"),
      // Block LS runs only when asked for (a block size other than 0).
      optional: ["blockls", "oe"],
      stepHint: 10,
    },
    {
      id: "malsm",
      number: 2,
      title: t("panel.malsm.title"),
      short: t("panel.malsm.tab"),
      intro: t("panel.malsm.intro"),
      fields: [...common, { name: "window", label: t("field.window"), ...r.window, integer: true, unit: t("unit.samples"), value: defaultOf("malsm", "window") }, setpoint(5), ...auto(4, 6)],
      methods: panelMethods("malsm"),
      automaticDefault: true,
      stepHint: 6,
    },
    {
      id: "wlsm",
      number: 3,
      title: t("panel.wlsm.title"),
      short: t("panel.wlsm.tab"),
      intro: t("panel.wlsm.intro"),
      fields: [
        ...common,
        { name: "gamma", label: t("field.gamma"), ...gamma, value: defaultOf("wlsm", "gamma") },
        { name: "pmax", label: t("field.pmax"), ...r.pmax, value: defaultOf("wlsm", "pmax") },
        { name: "a0", label: t("field.a0"), min: 0, max: 1, exclusiveMin: true, exclusiveMax: true, value: w0[0], unavailable: w0Note },
        { name: "b0", label: t("field.b0"), min: -1e6, max: 1e6, value: w0[1], unavailable: w0Note },
        setpoint(2),
        ...auto(0, 4),
      ],
      methods: panelMethods("wlsm"),
      automaticDefault: true,
      stepHint: 4,
    },
  ];
}
