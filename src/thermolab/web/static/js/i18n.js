// @ts-check
// The interface's words: t(key, params) looks a message up in the catalogue of
// the current language (messages/<lang>.js; English is built in and is the
// fallback for a key a translation lacks), fills its named placeholders
// ("Run {run} started.") and picks its plural form with Intl.PluralRules when
// the message has forms and params has a `count` (a "zero" form, when given,
// is used for exactly 0 in every language). Numbers, dates and times are
// written with Intl for the same language. Hand-written: it is forty lines, and
// every i18n library brings a format and a build step the lab does not need.

import { messages as english } from "./messages/en.js";

/** @typedef {string | Partial<Record<Intl.LDMLPluralRule, string>>} Message */
/** @typedef {Record<string, Message>} Catalogue */

/** @type {Catalogue} */
const fallback = english;
/** @type {Catalogue} */
let catalogue = english;
let lang = "en";
let plurals = new Intl.PluralRules(lang);

/** The language the interface speaks now (a BCP 47 tag). */
export function language() {
  return lang;
}

/**
 * Speak another language: its catalogue (keys it lacks stay English).
 * @param {string} tag  BCP 47 language tag, e.g. "pt-BR"
 * @param {Catalogue} messages
 */
export function setLanguage(tag, messages) {
  lang = tag;
  catalogue = messages;
  plurals = new Intl.PluralRules(tag);
  document.documentElement.lang = tag;
}

/**
 * The message `key` with its placeholders filled.
 * @param {string} key  a key of messages/en.js, written literally (the tests check them)
 * @param {Record<string, string | number | null | undefined>} [params]
 * @returns {string}
 */
export function t(key, params = {}) {
  const message = catalogue[key] ?? fallback[key];
  if (message === undefined) return key; // visible, and caught by the catalogue tests
  let text;
  if (typeof message === "string") text = message;
  else {
    const count = Number(params.count);
    // "zero" is also taken for exactly 0 in languages whose rules have no zero
    // form (English: "empty" rather than "0 waiting").
    const form = count === 0 && message.zero !== undefined ? "zero" : plurals.select(count);
    text = message[form] ?? message.other ?? key;
  }
  return text.replace(/\{([A-Za-z0-9]+)\}/g, (whole, name) => {
    const value = params[name];
    if (value === undefined || value === null) return whole;
    return name === "count" && typeof value === "number" ? formatNumber(value) : String(value);
  });
}

/**
 * A number in the current language's form (decimal comma in pt-BR).
 * @param {number} value
 * @param {Intl.NumberFormatOptions} [options]
 */
export function formatNumber(value, options) {
  return new Intl.NumberFormat(lang, options).format(value);
}

/**
 * A date and time in the current language's form.
 * @param {Date} date
 * @param {Intl.DateTimeFormatOptions} [options]  default: date and time
 */
export function formatDateTime(date, options = { dateStyle: "short", timeStyle: "medium" }) {
  return new Intl.DateTimeFormat(lang, options).format(date);
}

/**
 * A time of day in the current language's form.
 * @param {Date} date
 */
export function formatTime(date) {
  return new Intl.DateTimeFormat(lang, { timeStyle: "medium" }).format(date);
}

/**
 * Put the messages named by data-i18n attributes into the page's static
 * shell (index.html): data-i18n for the text, data-i18n-aria-label for
 * aria-label.
 * @param {ParentNode} root
 */
export function translatePage(root) {
  for (const el of root.querySelectorAll("[data-i18n]")) {
    const key = el.getAttribute("data-i18n");
    if (key) el.textContent = t(key);
  }
  for (const el of root.querySelectorAll("[data-i18n-aria-label]")) {
    const key = el.getAttribute("data-i18n-aria-label");
    if (key) el.setAttribute("aria-label", t(key));
  }
}
