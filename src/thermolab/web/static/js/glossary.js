// @ts-check
// The lab's core terms, one word per concept in each language (the catalogue's
// glossary.* keys): every other message uses the same word for the same thing
// (pt-BR: "bancada", never "equipamento"; an open-loop input is "entrada", the
// closed loop's target "referência"; role labels that fit anyone: "docente").
// tests/web/test_messages.py holds each language to its terms. The guide shows
// the list, so a student meets the words once, with what they mean.

import { h } from "./dom.js";
import { t } from "./i18n.js";

/** The concepts, in reading order, each with its term's key and its meaning's. */
export const GLOSSARY = Object.freeze([
  ["glossary.rig", "glossary.rig.means"],
  ["glossary.run", "glossary.run.means"],
  ["glossary.input", "glossary.input.means"],
  ["glossary.output", "glossary.output.means"],
  ["glossary.setpoint", "glossary.setpoint.means"],
  ["glossary.teacher", "glossary.teacher.means"],
  ["glossary.student", "glossary.student.means"],
]);

/** The glossary as a folded list ("Words used in this lab"). */
export function glossaryList() {
  const list = h("dl", { class: "glossary" });
  for (const [term, means] of GLOSSARY) list.append(h("dt", null, t(term)), h("dd", null, t(means)));
  return h("details", { class: "glossary small", "data-testid": "glossary" }, h("summary", null, t("glossary.heading")), list);
}
