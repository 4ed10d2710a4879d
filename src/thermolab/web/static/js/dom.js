// @ts-check
// Small DOM helpers. Text always goes in through textContent (never innerHTML),
// so names and messages from the server cannot inject markup.

import { DEFAULT_LANGUAGE, formatDateTime, language, t } from "./i18n.js";

/**
 * Create an element: h("button", {type: "button", onclick: f}, "Text", child).
 * Attributes starting with "on" become listeners; `class`, `for`, `aria-*`,
 * `data-*` and the rest are set as attributes; false/null/undefined are skipped.
 * @template {keyof HTMLElementTagNameMap} K
 * @param {K} tag
 * @param {Record<string, any> | null} [attrs]
 * @param {...(Node | string | number | null | undefined | false | Array<any>)} children
 * @returns {HTMLElementTagNameMap[K]}
 */
export function h(tag, attrs, ...children) {
  /** @type {any} */
  const el = document.createElement(tag);
  if (attrs) {
    for (const [key, value] of Object.entries(attrs)) {
      if (value === false || value === null || value === undefined) continue;
      if (key.startsWith("on") && typeof value === "function") {
        el.addEventListener(key.slice(2), value);
      } else if (key === "value" && "value" in el) {
        el.value = String(value);
      } else if (key === "checked" || key === "disabled" || key === "hidden") {
        el[key] = Boolean(value);
      } else {
        el.setAttribute(key, value === true ? "" : String(value));
      }
    }
  }
  append(el, children);
  return el;
}

function append(el, children) {
  for (const child of children) {
    if (child === null || child === undefined || child === false) continue;
    if (Array.isArray(child)) append(el, child);
    else el.append(child instanceof Node ? child : String(child));
  }
}

/** Replace an element's children. */
export function replaceChildren(el, ...children) {
  el.replaceChildren();
  append(el, children);
}

/** Set text only when it changed (avoids needless screen-reader chatter and layout). */
export function setText(el, text) {
  const s = String(text);
  if (el.textContent !== s) el.textContent = s;
}

let uid = 0;
/** A unique id for label/description wiring. */
export function nextId(prefix = "id") {
  uid += 1;
  return `${prefix}-${uid}`;
}

let politeTimer = null;
/**
 * Say something to screen-reader users (and show nothing). Polite messages
 * wait for the reader to finish; `alert` ones interrupt.
 * @param {string} message
 * @param {"polite" | "alert"} [urgency]
 */
export function announce(message, urgency = "polite") {
  const el = document.getElementById(urgency === "alert" ? "announce-alert" : "announce-polite");
  if (!el) return;
  // Clearing first makes a repeated identical message be read again.
  el.textContent = "";
  if (politeTimer !== null) clearTimeout(politeTimer);
  politeTimer = setTimeout(() => {
    el.textContent = message;
    politeTimer = null;
  }, 50);
}

/** "m:ss" (or "h:mm:ss") for a number of seconds; "–" when unknown. */
export function duration(seconds) {
  if (seconds === null || seconds === undefined || !Number.isFinite(seconds)) return "–";
  const s = Math.max(0, Math.round(seconds));
  const hh = Math.floor(s / 3600);
  const mm = Math.floor((s % 3600) / 60);
  const ss = String(s % 60).padStart(2, "0");
  return hh ? `${hh}:${String(mm).padStart(2, "0")}:${ss}` : `${mm}:${ss}`;
}

/** Spoken form of a duration: "4 minutes 5 seconds". */
export function durationWords(seconds) {
  if (seconds === null || seconds === undefined || !Number.isFinite(seconds)) return t("duration.unknown");
  const s = Math.max(0, Math.round(seconds));
  const m = Math.floor(s / 60);
  const r = s % 60;
  const parts = [];
  if (m) parts.push(t("duration.minutes", { count: m }));
  if (r || !m) parts.push(t("duration.seconds", { count: r }));
  return parts.join(" ");
}

/** An ISO instant as a datetime-local field's value, in local time. @param {string} iso */
export function localInput(iso) {
  const d = new Date(iso);
  const pad = (/** @type {number} */ n) => String(n).padStart(2, "0");
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}T${pad(d.getHours())}:${pad(d.getMinutes())}`;
}

/** Local date and time of an ISO instant, or "–". */
export function when(iso) {
  if (!iso) return "–";
  const d = new Date(iso);
  return Number.isNaN(d.getTime()) ? String(iso) : formatDateTime(d);
}

/**
 * A sentence the server wrote without a code to translate it by (an
 * estimate's or a run's reason): the server writes English (until its
 * messages are translated), so on a page in another language it is marked
 * lang="en" and screen readers pronounce it as English (WCAG 3.1.2).
 * @param {string} text
 * @returns {Node | string}
 */
export function serverText(text) {
  return language() === DEFAULT_LANGUAGE ? text : h("span", { lang: DEFAULT_LANGUAGE }, text);
}

/**
 * The message `key` as DOM children, where a parameter may be a node (e.g. a
 * serverText) placed where its placeholder stands.
 * @param {string} key
 * @param {Record<string, Node | string | number | null | undefined>} params
 * @returns {Array<Node | string>}
 */
export function tParts(key, params) {
  /** @type {Record<string, string | number | null | undefined>} */
  const flat = {};
  /** @type {Node[]} */
  const nodes = [];
  for (const [name, value] of Object.entries(params)) {
    if (value instanceof Node) {
      flat[name] = `\u0000${nodes.length}\u0000`;
      nodes.push(value);
    } else flat[name] = value;
  }
  return t(key, flat)
    .split("\u0000")
    .map((part, i) => (i % 2 ? nodes[Number(part)] : part))
    .filter((part) => part !== "");
}

/**
 * Show DOM children (tParts) in an element, touching it only when its text
 * changes (like setText: a live region is not re-announced for nothing).
 * @param {HTMLElement} el
 * @param {Array<Node | string>} parts
 */
export function setParts(el, parts) {
  const text = parts.map((p) => (typeof p === "string" ? p : p.textContent)).join("");
  if (el.textContent !== text) el.replaceChildren(...parts);
}
