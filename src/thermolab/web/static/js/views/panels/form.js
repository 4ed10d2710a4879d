// @ts-check
// One panel's forms: the settings form (START) with its checked fields, and
// the run controls (set point, END) shown while its run is going. Every field
// shows its allowed range and is checked before anything is sent.

import { h, nextId, setText } from "../../dom.js";
import { fmt } from "../../model.js";
import { checkAll, parseDecimal, rangeText } from "../../validate.js";
import { OFFSET_HINT, OFFSET_LABELS } from "./definitions.js";
import { formatDecimal, t } from "../../i18n.js";
import { unitSymbol } from "../../quantities.js";

/**
 * @typedef {object} PanelView  one panel's elements and definition
 * @property {any} def  its panelDefinitions entry
 * @property {Record<string, HTMLInputElement>} inputs  by field name
 * @property {Record<string, HTMLElement>} errors  each field's error text
 * @property {HTMLElement} [autoRow]
 * @property {HTMLInputElement} automatic  the Automatic (square wave) box
 * @property {HTMLInputElement} [planned]  the planned-step box (panels with plannedOnly fields)
 * @property {HTMLElement} [plannedRow]
 * @property {HTMLSelectElement} [offset]  the operating-point mode, when the server takes one
 * @property {HTMLSelectElement} [pair]  the input/output pair, when the rig has more than one
 * @property {HTMLFieldSetElement} fieldset
 * @property {HTMLButtonElement} startButton
 * @property {HTMLElement} formError
 * @property {HTMLInputElement} spInput  the set point while running
 * @property {HTMLElement} spError
 * @property {import("../../validate.js").FieldSpec} spSpec
 * @property {HTMLButtonElement} spButton
 * @property {HTMLButtonElement} endButton
 * @property {HTMLFieldSetElement} runFieldset
 * @property {HTMLElement} results
 * @property {HTMLElement} status
 * @property {HTMLElement} operatingPoint
 * @property {HTMLElement} el
 */

/**
 * Build one panel's view.
 * @param {any} def  a panelDefinitions entry
 * @param {{inputMin: number, inputMax: number, inputUnit: string, offsets?: string[] | null,
 *   pairs?: {input: string, output: string, label: string}[]}} limits
 * @param {string} panelId
 * @param {string} tabId
 * @param {{start: (view: PanelView) => void, setpoint: (view: PanelView) => void, end: (view: PanelView) => void}} on
 */
export function buildPanelView(def, limits, panelId, tabId, on) {
  /** @type {PanelView} */
  const view = /** @type {any} */ ({ def, inputs: {}, errors: {} });
  const formId = nextId("panel-form");
  const form = h("form", { novalidate: true, id: formId, class: "panel-form", "data-panel-form": def.id });
  const fieldset = h("fieldset", null, h("legend", null, t("panel.legend", { number: def.number, title: def.title })));
  const autoId = nextId("auto");
  const autoBox = h("input", { type: "checkbox", id: autoId, name: "automatic", checked: Boolean(def.automaticDefault) });
  const autoHint = h("span", { class: "hint", id: `${autoId}-hint` });
  if ((limits.pairs?.length ?? 0) > 1) {
    // The pair the run identifies: shown only where the rig has more than one (a kit).
    const id = `${def.id}-pair`;
    view.pair = h(
      "select",
      { id, name: "pair", "aria-describedby": `${id}-hint` },
      (limits.pairs ?? []).map((p) => h("option", { value: `${p.input}>${p.output}` }, p.label)),
    );
    fieldset.append(
      h("div", { class: "field" }, h("label", { for: id }, t("panel.pair")), view.pair, h("span", { class: "hint", id: `${id}-hint` }, t("panel.pairHint"))),
    );
  }
  for (const f of def.fields) {
    if (f.automaticOnly && !view.autoRow) {
      view.autoRow = h("div", { class: "field check" }, autoBox, h("label", { for: autoId }, t("panel.automatic")), autoHint);
      autoBox.setAttribute("aria-describedby", autoHint.id);
      fieldset.append(view.autoRow);
    }
    if (f.plannedOnly && !view.plannedRow) {
      const plannedId = nextId("planned");
      view.planned = h("input", { type: "checkbox", id: plannedId, name: "planned", "aria-describedby": `${plannedId}-hint` });
      view.plannedRow = h(
        "div",
        { class: "field check" },
        view.planned,
        h("label", { for: plannedId }, t("panel.plannedStep")),
        h("span", { class: "hint", id: `${plannedId}-hint` }, t("panel.plannedStepHint")),
      );
      fieldset.append(view.plannedRow);
    }
    fieldset.append(fieldRow(view, f));
  }
  if (limits.offsets?.length) {
    const id = `${def.id}-offset`;
    view.offset = h(
      "select",
      { id, name: "offset", "aria-describedby": `${id}-hint` },
      limits.offsets.map((mode) => h("option", { value: mode }, mode in OFFSET_LABELS ? t(OFFSET_LABELS[mode]) : mode)),
    );
    fieldset.append(
      h("div", { class: "field" }, h("label", { for: id }, t("panel.operatingPoint")), view.offset, h("span", { class: "hint", id: `${id}-hint` }, t(OFFSET_HINT))),
    );
  }
  view.automatic = autoBox;
  const updateAuto = () => {
    const automatic = autoBox.checked;
    const planned = Boolean(view.planned?.checked);
    for (const f of def.fields) {
      const row = /** @type {HTMLElement} */ (view.inputs[f.name].closest(".field"));
      if (f.automaticOnly) row.hidden = !automatic;
      if (f.manualOnly) row.hidden = automatic || (Boolean(f.plannedOnly) && !planned);
    }
    if (view.plannedRow) view.plannedRow.hidden = automatic;
    const dt = parseDecimal(view.inputs.dt.value) ?? Number.NaN;
    const freq = dt > 0 ? 1 / (10 * dt) : Number.NaN;
    setText(autoHint, t("panel.automaticHint", { frequency: fmt(freq, 3) }));
  };
  autoBox.addEventListener("change", updateAuto);
  view.planned?.addEventListener("change", updateAuto);
  view.inputs.dt.addEventListener("input", updateAuto);
  // START submits the settings form from the action bar, beside the set point and
  // END: on a phone the bar sits right under the chart (css: the phone layout).
  view.startButton = h("button", { type: "submit", form: formId, class: "primary", "data-action": "start" }, t("panel.start"));
  view.formError = h("p", { class: "error", role: "alert", "data-testid": "form-error" });
  form.append(fieldset, view.formError);
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    on.start(view);
  });
  view.fieldset = fieldset;
  const runForm = runControls(view, def, limits, on);
  view.results = h("div", { class: "results", "data-testid": `results-${def.id}` });
  view.status = h("p", { class: "run-status", "data-testid": `run-status-${def.id}` });
  view.operatingPoint = h("p", { class: "hint", "data-testid": `operating-point-${def.id}` });
  view.el = h(
    "div",
    { role: "tabpanel", id: panelId, "aria-labelledby": tabId, class: "panel", tabindex: "0", "data-panel-view": def.id },
    h("p", { class: "panel-intro" }, def.intro),
    form,
    h("div", { class: "action-bar", "data-testid": `action-bar-${def.id}` }, runForm, h("div", { class: "buttons start" }, view.startButton)),
    h("div", { class: "panel-results" }, h("h3", null, t("panel.model")), view.status, view.operatingPoint, view.results),
  );
  updateAuto();
  return view;
}

/** The run controls: change the set point while running, END. */
function runControls(view, def, limits, on) {
  const spId = nextId("sp");
  const spSpec = { label: t("panel.setpoint"), min: limits.inputMin, max: limits.inputMax, unit: unitSymbol(limits.inputUnit) };
  view.spInput = h("input", {
    id: spId,
    name: "setpoint-live",
    type: "text",
    inputmode: limits.inputMin >= 0 ? "decimal" : null,
    value: typeof def.stepHint === "number" ? formatDecimal(def.stepHint) : def.stepHint,
    "aria-describedby": `${spId}-range ${spId}-err`,
  });
  view.spError = h("span", { class: "field-error", id: `${spId}-err` });
  view.spButton = h("button", { type: "submit", "data-action": "setpoint" }, t("panel.changeSetpoint"));
  view.endButton = h("button", { type: "button", class: "danger", "data-action": "end" }, t("panel.end"));
  view.spSpec = spSpec;
  const runForm = h(
    "form",
    { novalidate: true, class: "run-controls", "data-run-form": def.id },
    h(
      "fieldset",
      null,
      h("legend", null, t("panel.whileRunning")),
      h(
        "div",
        { class: "field" },
        h("label", { for: spId }, t("panel.setpoint")),
        view.spInput,
        h("span", { class: "hint", id: `${spId}-range` }, t("field.allowed", { range: rangeText(spSpec) })),
        view.spError,
      ),
      h("div", { class: "buttons" }, view.spButton, view.endButton),
    ),
  );
  runForm.addEventListener("submit", (ev) => {
    ev.preventDefault();
    on.setpoint(view);
  });
  view.endButton.addEventListener("click", () => on.end(view));
  view.runFieldset = runForm.querySelector("fieldset");
  return runForm;
}

function fieldRow(view, f) {
  const id = `${view.def.id}-${f.name}`;
  const input = h("input", {
    id,
    name: f.name,
    type: "text",
    // iOS's decimal keypad has no minus sign: offer it only where negatives are not allowed.
    inputmode: f.min >= 0 ? (f.integer ? "numeric" : "decimal") : null,
    value: typeof f.value === "number" ? formatDecimal(f.value) : f.value,
    autocomplete: "off",
    "aria-describedby": `${id}-range ${id}-err`,
    disabled: Boolean(f.unavailable),
  });
  const err = h("span", { class: "field-error", id: `${id}-err` });
  view.inputs[f.name] = input;
  view.errors[f.name] = err;
  input.addEventListener("input", () => {
    if (input.getAttribute("aria-invalid") === "true") showFieldError(view, f.name, null);
  });
  return h(
    "div",
    { class: "field" },
    h("label", { for: id }, f.label + (f.unit && f.unit !== "samples" ? ` (${f.unit})` : "")),
    input,
    h("span", { class: "hint", id: `${id}-range` }, f.unavailable ?? t("field.allowed", { range: rangeText(f) })),
    err,
  );
}

/** Mark a field invalid with its message, or clear it (message null). */
export function showFieldError(view, name, message) {
  const input = view.inputs[name];
  if (message) {
    input.setAttribute("aria-invalid", "true");
    setText(view.errors[name], message);
  } else {
    input.removeAttribute("aria-invalid");
    setText(view.errors[name], "");
  }
}

/** Check the panel's fields; returns the values or null (errors shown, focus on the first). */
export function checkPanel(view) {
  const automatic = view.automatic.checked;
  const planned = !automatic && Boolean(view.planned?.checked);
  /** @type {Record<string, any>} */
  const specs = {};
  /** @type {Record<string, string>} */
  const texts = {};
  for (const f of view.def.fields) {
    if ((f.automaticOnly && !automatic) || (f.manualOnly && automatic) || (f.plannedOnly && !planned) || f.unavailable) {
      showFieldError(view, f.name, null);
      continue;
    }
    specs[f.name] = f;
    texts[f.name] = view.inputs[f.name].value;
  }
  const { values, errors } = checkAll(texts, specs);
  if (!errors.window && values.window !== undefined && values.n !== undefined && values.window > values.n) {
    errors.window = t("panel.windowTooLong", { samples: values.n });
  }
  if (automatic && !errors.low && !errors.high && !(values.low < values.high)) {
    errors.high = t("panel.automaticOrder");
  }
  if (planned && !errors.stepAt && !errors.dt && !errors.n && !(values.stepAt < values.n * values.dt)) {
    errors.stepAt = t("panel.stepAfterEnd", { seconds: formatDecimal(values.n * values.dt) });
  }
  if (!errors.block && values.block > 0) {
    const min = view.def.fields.find((f) => f.name === "block").blockMin;
    if (values.block < min || values.block > values.n) {
      errors.block = t("panel.blockRange", { min, samples: values.n ?? "?" });
    }
  }
  let first = null;
  for (const f of view.def.fields) {
    const msg = errors[f.name] ?? null;
    if (specs[f.name] || msg) showFieldError(view, f.name, msg);
    if (msg && !first) first = view.inputs[f.name];
  }
  if (first) {
    setText(view.formError, t("panel.correctFields"));
    first.focus();
    return null;
  }
  setText(view.formError, "");
  if (view.offset) values.offset = view.offset.value;
  if (view.pair) values.pair = view.pair.value;
  return { values, automatic };
}
