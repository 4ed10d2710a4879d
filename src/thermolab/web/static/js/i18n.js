// @ts-check
// The interface's words: t(key, params) looks a message up in the catalogue of
// the current language (messages/<lang>.js; English is built in and is the
// fallback for a key a translation lacks), fills its named placeholders
// ("Run {run} started.") and picks its plural form with Intl.PluralRules when
// the message has forms and params has a `count` (a "zero" form, when given,
// is used for exactly 0 in every language). Numbers, dates and times are
// written with Intl for the same language. Hand-written: it is forty lines, and
// every i18n library brings a format and a build step the lab does not need.
//
// The interface speaks Brazilian Portuguese, English and Spanish (LANGUAGES):
// English is loaded with the page; the others are loaded on demand (dynamic
// import) when chosen. The choice is the one remembered in localStorage, else
// the best match of the browser's navigator.languages (negotiateLanguage).

import { messages as english } from "./messages/en.js";

/** @typedef {string | Partial<Record<Intl.LDMLPluralRule, string>>} Message */
/** @typedef {Record<string, Message>} Catalogue */

/**
 * The languages of the interface, by BCP 47 tag: the key of the language's
 * name (each catalogue names every language in that language's own words, so
 * the switcher reads the same in all of them) and the loader of its catalogue.
 * @type {Record<string, {name: string, load: () => Promise<{messages: Catalogue}>}>}
 */
export const LANGUAGES = {
  "pt-BR": { name: "language.pt-BR", load: () => import("./messages/pt-BR.js") },
  en: { name: "language.en", load: async () => ({ messages: english }) },
  es: { name: "language.es", load: () => import("./messages/es.js") },
};
/** The language spoken when the browser prefers none of LANGUAGES. */
export const DEFAULT_LANGUAGE = "en";
/** Where the reader's own choice is remembered (localStorage). */
export const LANGUAGE_STORAGE_KEY = "thermolab.language";

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
 * The best of LANGUAGES for a list of preferred BCP 47 tags, most preferred
 * first (navigator.languages): an exact match (case-insensitive) first, then
 * the same primary language ("pt", "pt-PT" -> "pt-BR"; "es-MX" -> "es";
 * "en-GB" -> "en"); DEFAULT_LANGUAGE when nothing matches.
 * @param {readonly string[]} preferences
 * @returns {string}
 *
 * @example negotiateLanguage(["pt-PT", "en"]) // "pt-BR"
 */
export function negotiateLanguage(preferences) {
  const tags = Object.keys(LANGUAGES);
  for (const wanted of preferences) {
    const lower = String(wanted).trim().toLowerCase();
    if (!lower) continue;
    const exact = tags.find((tag) => tag.toLowerCase() === lower);
    if (exact) return exact;
    const primary = lower.split(/[-_]/)[0];
    const same = tags.find((tag) => tag.toLowerCase().split("-")[0] === primary);
    if (same) return same;
  }
  return DEFAULT_LANGUAGE;
}

/**
 * The language to start in: the reader's remembered choice, else the
 * browser's preference.
 * @returns {string}
 */
export function preferredLanguage() {
  let stored = null;
  try {
    stored = window.localStorage.getItem(LANGUAGE_STORAGE_KEY);
  } catch {
    // Storage refused (private mode, sandboxed frame): the browser's preference still holds.
  }
  if (stored && stored in LANGUAGES) return stored;
  const prefs = navigator.languages?.length ? navigator.languages : [navigator.language ?? ""];
  return negotiateLanguage(prefs);
}

/**
 * Load `tag`'s catalogue and speak it; `remember` keeps the choice for the
 * next visit. An unknown tag is negotiated to the nearest language first.
 * @param {string} tag
 * @param {{remember?: boolean}} [opts]
 * @returns {Promise<string>} the language now spoken
 */
export async function useLanguage(tag, opts = {}) {
  const chosen = tag in LANGUAGES ? tag : negotiateLanguage([tag]);
  const { messages } = await LANGUAGES[chosen].load();
  setLanguage(chosen, messages);
  if (opts.remember) {
    try {
      window.localStorage.setItem(LANGUAGE_STORAGE_KEY, chosen);
    } catch {
      // Not remembered; the choice still holds for this page.
    }
  }
  return chosen;
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
    if (typeof value !== "number") return String(value);
    // Counts read as numbers ("1.234 amostras"); other whole numbers are
    // identifiers and sample indices, written plainly; fractions take the
    // language's decimal mark.
    if (name === "count") return formatNumber(value);
    return Number.isInteger(value) ? String(value) : formatDecimal(value);
  });
}

/**
 * A message from the server in the reader's language: the answer's stable
 * `code` names the catalogue message "error.<code>" (filled with `params`);
 * when the catalogue has no such message (a server newer than the page, or a
 * code not translated yet) the server's own text, `detail`, is shown.
 * @param {unknown} code
 * @param {string} detail
 * @param {Record<string, string | number | null | undefined>} [params]
 * @returns {string}
 */
export function serverMessage(code, detail, params = {}) {
  if (typeof code !== "string" || !/^[A-Za-z0-9_.-]+$/.test(code)) return detail;
  const key = `error.${code}`;
  return key in catalogue || key in fallback ? t(key, params) : detail;
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
 * A number as a reader would type it back into a field: JavaScript's
 * shortest form that reads back as the same number (so a default shown in a
 * field is sent unchanged), with the language's decimal mark and a true minus
 * sign; no grouping.
 * @param {number} value
 * @returns {string}
 *
 * @example formatDecimal(-0.96) // "−0.96" in English, "−0,96" in pt-BR
 */
export function formatDecimal(value) {
  return String(value).replace(".", decimalMark()).replace(/^-/, "−");
}

/** The current language's decimal mark ("." or ","). */
export function decimalMark() {
  return new Intl.NumberFormat(lang).formatToParts(0.5).find((p) => p.type === "decimal")?.value ?? ".";
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
