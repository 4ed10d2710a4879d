// @ts-check
// The closed-loop panel's tuning table (GET /api/runs/{id}/tuning): each rule's
// gains for the run's identified model, with the predicted step to the set point;
// a rule that cannot tune the model says why. The panel (../closedloop.js) owns
// what a row's "use" does.

import { pairEnd } from "../../channelwords.js";
import { h } from "../../dom.js";
import { formatNumber, t } from "../../i18n.js";
import { loopWord } from "../../loopwords.js";
import { unitSymbol } from "../../quantities.js";

/** A figure for the table and the panel: four significant digits, "–" for none. @param {number | null | undefined} v @param {number} [digits] */
export function num(v, digits = 4) {
  return v === null || v === undefined || !Number.isFinite(v) ? "–" : formatNumber(v, { maximumSignificantDigits: digits });
}

/**
 * The table's elements: the model, its pair (where the rig has more than one), the step, the rows.
 * @param {any} table the server's table
 * @param {{outputUnit: string, inputUnit: string}} rig the rig's units
 * @param {boolean} showPair whether the rig has more than one heater and sensor pair
 * @param {(row: any) => void} onUse a row's "use" pressed
 * @returns {HTMLElement[]}
 */
export function tuningTable(table, rig, showPair, onUse) {
  const out = unitSymbol(rig.outputUnit);
  const rows = table.rows.map((/** @type {any} */ row) => {
    const name = h("th", { scope: "row" }, `${row.rule.toUpperCase()} ${row.form.toUpperCase()}`);
    // A rule that cannot tune this model says why (ZN and CC need a dead time), in the page's language.
    if (row.error) return h("tr", { "data-refused": `${row.rule}-${row.form}` }, name, h("td", { colspan: "7", class: "hint" }, loopWord(row.why, row.error)));
    const use = h("button", { type: "button", "data-action": "use", "data-rule": `${row.rule}-${row.form}` }, t("loop.use"));
    use.addEventListener("click", () => onUse(row));
    const p = row.predicted;
    return h("tr", {}, name,
      h("td", {}, num(row.Kp)), h("td", {}, num(row.Ti)), h("td", {}, num(row.Td)),
      h("td", {}, num(p.overshoot, 3)), h("td", {}, num(p.settling_time, 4)), h("td", {}, num(p.iae)), h("td", {}, use));
  });
  const m = table.model;
  const heads = ["loop.rule", "loop.kp", "loop.ti", "loop.td", "loop.overshoot", "loop.settling", "loop.iae"];
  return [
    h("p", {}, t("loop.model", { K: num(m.K), tau: num(m.tau), theta: num(m.theta), method: table.method.toUpperCase() })),
    // Which heater and sensor the model is of, where the rig has more than one pair.
    ...(showPair && table.pair ? [h("p", { "data-testid": "tuning-pair" }, t("loop.modelPair", { input: pairEnd(table.pair.input, true), output: pairEnd(table.pair.output, true) }))] : []),
    h("p", { "data-testid": "tuning-step" }, t("loop.tuningStep", { from: num(table.y0), to: num(table.setpoint), unit: out, u0: num(table.u0), inputUnit: unitSymbol(rig.inputUnit) })),
    h("table", {}, h("thead", {}, h("tr", {}, ...heads.map((k) => h("th", { scope: "col" }, t(k))), h("th", {}))),
      h("tbody", {}, ...rows)),
  ];
}
