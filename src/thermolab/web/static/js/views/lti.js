// @ts-check
// A teacher's LMS page (LTI 1.3): the URLs to give the LMS, the platforms
// registered (register, remove), the tool's key (rotate), a course's roster
// synchronised from its LMS, and the grade outbox with its failures (retry).

import { ltiApi } from "../lti-api.js";
import { announce, h, setText, when } from "../dom.js";
import { t } from "../i18n.js";

const FIELDS = [
  ["issuer", "lti.issuer", "url"],
  ["clientId", "lti.clientId", "text"],
  ["authLoginUrl", "lti.authLoginUrl", "url"],
  ["tokenUrl", "lti.tokenUrl", "url"],
  ["jwksUrl", "lti.jwksUrl", "url"],
  ["deploymentIds", "lti.deploymentIds", "text"],
];

/** The words of a queued grade's state. */
const STATUS = { pending: "lti.gradePending", sent: "lti.gradeSent", failed: "lti.gradeFailed" };

/**
 * @param {HTMLElement} main
 * @param {{query: URLSearchParams}} _route
 * @param {any} ctx
 */
export function mount(main, _route, ctx) {
  if (ctx.user?.role !== "teacher") {
    main.append(h("h1", null, t("lti.heading")), h("p", { class: "error" }, t("lti.only")));
    return null;
  }
  let alive = true;
  const error = h("p", { class: "error", id: "lti-error", role: "alert" });
  const tool = h("dl", { id: "lti-tool" });
  const platforms = h("ul", { id: "lti-platforms" });
  const grades = h("tbody", { id: "lti-grades" });
  /** @type {Record<string, HTMLInputElement>} */
  const inputs = {};
  const register = h("button", { type: "submit", class: "primary" }, t("lti.register"));
  const form = h(
    "form",
    { class: "card", id: "lti-form", novalidate: true, "aria-describedby": "lti-error" },
    h("h2", null, t("lti.registerHeading")),
    ...FIELDS.map(([name, key, type]) => {
      const id = `lti-${name}`;
      inputs[name] = /** @type {HTMLInputElement} */ (h("input", { id, name, type, required: true, autocomplete: "off", spellcheck: "false", maxlength: "1024" }));
      return h("div", { class: "field" }, h("label", { for: id }, t(key)), inputs[name]);
    }),
    h("p", { class: "muted" }, t("lti.deploymentHelp")),
    error,
    register,
  );
  const rotate = h("button", { type: "button", id: "lti-rotate" }, t("lti.rotate"));
  const course = h("input", { id: "lti-course", name: "course", maxlength: "64", autocomplete: "off", autocapitalize: "none" });
  const sync = h("button", { type: "button", id: "lti-sync" }, t("lti.sync"));
  const syncReport = h("p", { id: "lti-sync-report", "aria-live": "polite" });

  async function refresh() {
    const [urls, known, queued] = await Promise.all([ltiApi.tool(), ltiApi.platforms(), ltiApi.grades()]);
    if (!alive) return;
    tool.replaceChildren(
      ...[["lti.loginUrl", urls.loginUrl], ["lti.launchUrl", urls.launchUrl], ["lti.toolJwksUrl", urls.jwksUrl]].flatMap(([key, url]) => [h("dt", null, t(key)), h("dd", null, h("code", null, url))]),
    );
    platforms.replaceChildren(
      ...(known.length === 0
        ? [h("li", { class: "muted" }, t("lti.noPlatforms"))]
        : known.map((p) => {
            const remove = h("button", { type: "button", class: "danger" }, t("lti.remove"));
            remove.addEventListener("click", () => act(() => ltiApi.removePlatform(p.id), t("lti.removed", { issuer: p.issuer })));
            return h("li", { "data-platform": p.issuer }, h("span", null, t("lti.platformLine", { issuer: p.issuer, client: p.clientId, deployments: p.deploymentIds.join(", ") })), " ", remove);
          })),
    );
    grades.replaceChildren(
      ...(queued.length === 0
        ? [h("tr", null, h("td", { colspan: "5", class: "muted" }, t("lti.noGrades")))]
        : queued.map((g) => {
            const cells = [
              h("td", null, g.sub),
              h("td", null, `${g.scoreGiven} / ${g.scoreMaximum}`),
              h("td", null, t(STATUS[g.status] ?? "lti.gradePending")),
              h("td", null, g.lastError ?? (g.sentAt ? when(g.sentAt) : "")),
            ];
            const retry = h("button", { type: "button" }, t("lti.retry"));
            retry.addEventListener("click", () => act(() => ltiApi.retryGrade(g.id), t("lti.retried")));
            return h("tr", { "data-grade": g.status }, ...cells, h("td", null, g.status === "sent" ? "" : retry));
          })),
    );
  }

  /** @param {() => Promise<any>} call @param {string} done */
  async function act(call, done) {
    setText(error, "");
    try {
      await call();
      announce(done);
      await refresh();
    } catch (err) {
      setText(error, err.message);
    }
  }

  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    const empty = Object.values(inputs).find((el) => !el.value.trim());
    if (empty) {
      setText(error, t("lti.missing"));
      empty.focus();
      return;
    }
    const spec = Object.fromEntries(Object.entries(inputs).map(([k, el]) => [k, el.value.trim()]));
    const deploymentIds = spec.deploymentIds.split(/[\s,]+/).filter(Boolean);
    register.disabled = true;
    await act(() => ltiApi.register({ ...spec, deploymentIds }), t("lti.registered", { issuer: spec.issuer }));
    register.disabled = false;
    if (!error.textContent) form.reset();
  });
  rotate.addEventListener("click", () => act(() => ltiApi.rotateKey(), t("lti.rotated")));
  sync.addEventListener("click", async () => {
    setText(error, "");
    try {
      const report = await ltiApi.syncRoster(course.value.trim());
      setText(syncReport, t("lti.synced", { added: report.added.length, removed: report.removed.length, kept: report.kept }));
    } catch (err) {
      setText(error, err.message);
    }
  });

  main.append(
    h("h1", null, t("lti.heading")),
    h("p", { class: "lede" }, t("lti.lede")),
    h("section", { class: "card" }, h("h2", null, t("lti.toolHeading")), tool, rotate),
    h("section", { class: "card" }, h("h2", null, t("lti.platformsHeading")), platforms),
    form,
    h("section", { class: "card" }, h("h2", null, t("lti.rosterHeading")), h("div", { class: "field" }, h("label", { for: "lti-course" }, t("lti.course")), course), sync, syncReport),
    h(
      "section",
      { class: "card" },
      h("h2", null, t("lti.gradesHeading")),
      h("table", null, h("thead", null, h("tr", null, ...["lti.gradeUser", "lti.gradeScore", "lti.gradeStatus", "lti.gradeNote", "lti.gradeAction"].map((k) => h("th", { scope: "col" }, t(k))))), grades),
    ),
  );
  refresh().catch((err) => setText(error, err.message));
  return () => {
    alive = false;
  };
}
