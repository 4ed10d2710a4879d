// @ts-check
// The single-page application: session, hash router, navigation.
//
// Each view is a module exporting mount(container, params, ctx) that returns a
// cleanup function; the router calls it when leaving the page, so sockets,
// timers and observers never outlive their page (memory stays bounded however
// long the tab stays open).

import { api, ApiError, setUnauthorizedHandler } from "./api.js";
import { announce, h, replaceChildren, setText } from "./dom.js";
import { LANGUAGES, language, preferredLanguage, t, translatePage, useLanguage } from "./i18n.js";
import { loadMethods } from "./methods.js";
import { personName } from "./shapes.js";

/** Routes: pattern → view module loader. The first match wins. */
const ROUTES = [
  { pattern: /^\/login$/, view: () => import("./views/login.js"), title: "login.title", open: true },
  { pattern: /^\/$/, view: () => import("./views/lobby.js"), title: "nav.rigs", nav: "lobby" },
  { pattern: /^\/rig\/([^/]+)$/, view: () => import("./views/rig.js"), title: "rig.pageTitle", nav: "lobby" },
  { pattern: /^\/runs$/, view: () => import("./views/runs.js"), title: "nav.runs", nav: "runs" },
  { pattern: /^\/runs\/compare$/, view: () => import("./views/compare.js"), title: "compare.title", nav: "runs" },
  { pattern: /^\/runs\/([^/]+)$/, view: () => import("./views/run.js"), title: "run.pageTitle", nav: "runs" },
  { pattern: /^\/teacher$/, view: () => import("./views/teacher.js"), title: "nav.teacher", nav: "teacher" },
  { pattern: /^\/hosts$/, view: () => import("./views/hosts.js"), title: "hosts.title", nav: "teacher" },
  { pattern: /^\/audit$/, view: () => import("./views/audit.js"), title: "audit.title", nav: "teacher" },
  { pattern: /^\/account$/, view: () => import("./views/account.js"), title: "nav.account", nav: "account" },
  { pattern: /^\/courses$/, view: () => import("./views/courses.js"), title: "nav.courses", nav: "courses" },
  { pattern: /^\/assignments$/, view: () => import("./views/assignments.js"), title: "nav.assignments", nav: "assignments" },
  { pattern: /^\/assignments\/(\d+)$/, view: () => import("./views/assignments.js"), title: "nav.assignments", nav: "assignments" },
  { pattern: /^\/analytics$/, view: () => import("./views/analytics.js"), title: "analytics.title", nav: "courses" },
  { pattern: /^\/enrol$/, view: () => import("./views/enrol.js"), title: "enrol.title", open: true },
  { pattern: /^\/privacy$/, view: () => import("./views/privacy.js"), title: "privacy.heading", open: true },
  { pattern: /^\/bookings$/, view: () => import("./views/bookings.js"), title: "nav.bookings", nav: "bookings" },
  { pattern: /^\/lti$/, view: () => import("./views/lti.js"), title: "lti.heading", nav: "lti" },
  { pattern: /^\/lti\/deep-link\/([A-Za-z0-9_-]+)$/, view: () => import("./views/deeplink.js"), title: "deeplink.heading", nav: "lti" },
  { pattern: /^\/password$/, view: () => import("./views/password.js"), title: "password.heading", nav: "account" },
];

/** Shared state handed to every view. */
export const ctx = {
  /** @type {{username: string, displayName?: string | null, role: string, mustChangePassword?: boolean, admin?: boolean} | null} */
  user: null,
  navigate,
  afterLogin,
  landing,
  /** Set the page title (the document title and the first heading's text). */
  setTitle(text) {
    document.title = t("app.documentTitle", { page: text });
  },
};

let cleanup = null;
let renderToken = 0;
/** Whether the session is known: a page moved to before that is shown once it is. */
let sessionKnown = false;

/** Parse "#/path?a=1" into a path and its query. */
export function parseHash(hash) {
  const raw = hash.replace(/^#/, "") || "/";
  const q = raw.indexOf("?");
  const path = q === -1 ? raw : raw.slice(0, q);
  const query = new URLSearchParams(q === -1 ? "" : raw.slice(q + 1));
  return { path: path.startsWith("/") ? path : `/${path}`, query };
}

export function navigate(path) {
  if (window.location.hash === `#${path}`) void render();
  else window.location.hash = path;
}

async function loadSession() {
  try {
    ctx.user = normaliseUser(await api.session());
  } catch (err) {
    if (!(err instanceof ApiError) || (err.status !== 401 && err.status !== 404)) throw err;
    ctx.user = null;
  }
  updateChrome();
}

/** The session answer may wrap the user or be the user itself. */
export function normaliseUser(data) {
  if (!data || typeof data !== "object") return null;
  const u = data.user && typeof data.user === "object" ? data.user : data;
  if (typeof u.username !== "string") return null;
  return { ...u, username: u.username, role: u.role ?? "student" };
}

/**
 * An element of the page shell (index.html), which is always there.
 * @param {string} id
 * @returns {HTMLElement}
 */
function shell(id) {
  const el = document.getElementById(id);
  if (!el) throw new TypeError(`index.html has no #${id}`);
  return el;
}

/** The translated words for a user's role (others show the server's word). */
const ROLE_TEXT = { student: "role.student", teacher: "role.teacher" };

function updateChrome() {
  const user = ctx.user;
  shell("nav").hidden = user === null;
  shell("who").hidden = user === null;
  shell("nav-teacher").hidden = user?.role !== "teacher";
  shell("nav-courses").hidden = user?.role !== "teacher";
  setText(shell("who-name"), user ? t("app.who", { user: personName(user.username, user.displayName, true), role: ROLE_TEXT[user.role] ? t(ROLE_TEXT[user.role]) : user.role }) : "");
  shell("nav-lti").hidden = user?.role !== "teacher";
}

function markNav(name) {
  for (const a of /** @type {NodeListOf<HTMLElement>} */ (document.querySelectorAll("[data-nav]"))) {
    if (a.dataset.nav === name) a.setAttribute("aria-current", "page");
    else a.removeAttribute("aria-current");
  }
}

/**
 * Show the current page (again).
 * @param {{keepFocus?: boolean}} [opts]  keepFocus: leave focus where it is
 *   (on the language switcher) instead of moving it to the new page
 */
async function render(opts = {}) {
  const token = ++renderToken;
  const { path, query } = parseHash(window.location.hash);
  const route = ROUTES.find((r) => r.pattern.test(path));
  const main = shell("main");
  if (cleanup) {
    const fn = cleanup;
    cleanup = null;
    try {
      fn();
    } catch (err) {
      console.error(err);
    }
  }
  if (!route) {
    replaceChildren(main, h("h1", null, t("app.notFound")), h("p", null, h("a", { href: "#/" }, t("app.backToRigs"))));
    ctx.setTitle(t("app.notFound"));
    return;
  }
  if (!route.open && ctx.user === null) {
    const back = path === "/" ? "" : `?next=${encodeURIComponent(path + (query.toString() ? `?${query}` : ""))}`;
    navigate(`/login${back}`);
    return;
  }
  if (ctx.user?.mustChangePassword && path !== "/password") {
    // A temporary password opens nothing else (the server refuses every other request).
    navigate("/password");
    return;
  }
  markNav(route.nav ?? "");
  ctx.setTitle(t(route.title));
  const params = path.match(route.pattern).slice(1).map(decodeURIComponent);
  let mod;
  try {
    // The identification methods (GET /api/methods) before any view builds panels or results.
    // (Not with a temporary password: the server answers nothing but the password change.)
    if (!route.open && !ctx.user?.mustChangePassword) await loadMethods();
    mod = await viewModule(route);
  } catch (err) {
    replaceChildren(main, h("p", { class: "error" }, t("app.pageFailed", { error: String(err) })));
    return;
  }
  if (token !== renderToken) return; // the user moved on while the module loaded
  main.replaceChildren();
  const result = mod.mount(main, { params, query }, ctx);
  cleanup = typeof result === "function" ? result : null;
  if (opts.keepFocus) return;
  // Move focus to the new page so keyboard and screen-reader users start there.
  const heading = main.querySelector("h1");
  if (heading) {
    heading.setAttribute("tabindex", "-1");
    heading.focus({ preventScroll: false });
  } else {
    main.focus();
  }
}

/** When the page was last loaded again for a view's module the network lost (sessionStorage). */
const RELOADED_AT = "thermolab.reloadedForModule";

/**
 * A route's view module, fetched a second time when the network lost it.
 *
 * A module the browser could not fetch (a connection dropped, a phone between
 * networks) fails the import with a TypeError; a browser may keep that failure
 * for the document's life, so when the second try fails too, the page loads
 * itself again, at most once a minute (a lab that is really unreachable then
 * shows its error instead of reloading for ever). A module's own error (a
 * SyntaxError, say) is no network loss and is shown at once.
 * @param {{view: () => Promise<any>}} route
 */
async function viewModule(route) {
  try {
    return await route.view();
  } catch (err) {
    if (!(err instanceof TypeError)) throw err;
  }
  await new Promise((resolve) => setTimeout(resolve, 300));
  try {
    return await route.view();
  } catch (err) {
    if (!(err instanceof TypeError) || !reloadOnce()) throw err;
    return new Promise(() => {}); // the page is being loaded again
  }
}

/** Load the page again unless that was done in the last minute; whether it is. */
function reloadOnce() {
  try {
    const last = Number(window.sessionStorage.getItem(RELOADED_AT) ?? 0);
    if (Date.now() - last < 60_000) return false;
    window.sessionStorage.setItem(RELOADED_AT, String(Date.now()));
  } catch {
    return false; // no session storage (a private window may refuse it): no reload loop either
  }
  window.location.reload();
  return true;
}

async function logout() {
  try {
    await api.logout();
  } catch {
    // Logging out of an expired session is still logging out.
  }
  ctx.user = null;
  updateChrome();
  announce(t("app.loggedOut"));
  navigate("/login");
}

/** Called by the login view after a successful login. */
async function afterLogin(next) {
  await loadSession();
  navigate(landing(next));
}

/**
 * Where a logged-in user goes from the login page: the page they were sent
 * there from (`next`, a path of this app), else the rigs.
 * @param {string | null} next
 */
function landing(next) {
  return next && next.startsWith("/") && !next.startsWith("/login") ? next : "/";
}

/** The header's language switcher: one option per language, named in its own words. */
function setUpLanguageSwitcher() {
  const select = /** @type {HTMLSelectElement} */ (shell("language"));
  select.replaceChildren(
    ...Object.entries(LANGUAGES).map(([tag, { name }]) => h("option", { value: tag, lang: tag }, t(name))),
  );
  select.value = language();
  select.addEventListener("change", () => void switchLanguage(select.value));
}

/**
 * Speak another language now and next time: the shell is translated in place
 * and the current view is mounted again (its sockets reconnect and replay the
 * run's history), so every message, number and date is re-rendered without
 * reloading the page.
 * @param {string} tag
 */
async function switchLanguage(tag) {
  try {
    await useLanguage(tag, { remember: true });
  } catch (err) {
    announce(t("app.pageFailed", { error: String(err) }), "alert");
    return;
  }
  translatePage(document);
  updateChrome();
  await render({ keepFocus: true });
}

async function start() {
  try {
    await useLanguage(preferredLanguage());
  } catch (err) {
    // The catalogue could not be loaded: English is built in and still works.
    console.error(err);
  }
  translatePage(document);
  setUpLanguageSwitcher();
  setUnauthorizedHandler(() => {
    if (ctx.user === null) return;
    ctx.user = null;
    updateChrome();
    announce(t("app.sessionEnded"), "alert");
    navigate("/login");
  });
  shell("logout").addEventListener("click", logout);
  // A page moved to while the language and the session load is shown by the render
  // below (it reads the address then): rendered now, it would send a logged-in user
  // to the login page, as if logged out.
  window.addEventListener("hashchange", () => {
    if (sessionKnown) void render();
  });
  try {
    await loadSession();
  } catch (err) {
    replaceChildren(
      shell("main"),
      h("h1", null, t("app.name")),
      h("p", { class: "error", role: "alert" }, t("app.unreachable", { error: err.message ?? String(err) })),
      h("button", { type: "button", onclick: () => window.location.reload() }, t("app.tryAgain")),
    );
    return;
  }
  sessionKnown = true;
  await render();
}

if (typeof window !== "undefined" && document.getElementById("main")) void start();
