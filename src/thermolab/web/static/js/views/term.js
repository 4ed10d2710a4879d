// @ts-check
// The end of a course's term, on its page: close it (read-only from then on:
// no enrolment, hand-in, booking or edit; reads and exports go on), and copy
// it to the next term (its rigs, limits, assignments as drafts and booking
// pattern, moved to the new term's first day; no students, runs or marks).

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { formatDateTime, t } from "../i18n.js";

/**
 * @param {{name: string, title: string, closedAt?: string | null, closedBy?: string | null}} course
 * @param {any} ctx
 */
export function endOfTermSection(course, ctx) {
  const out = h("p", { role: "status", id: "term-result" });
  const state = h("p", { id: "term-state" });
  const close = h("button", { type: "button", id: "term-close" }, t("term.close"));
  const confirm = h("button", { type: "button", class: "danger", id: "term-close-confirm", hidden: true }, t("term.closeConfirm"));

  /** @param {string | null | undefined} at @param {string | null | undefined} by */
  function showState(at, by) {
    const closed = Boolean(at);
    setText(state, closed ? t("term.closedOn", { date: formatDateTime(new Date(String(at)), { dateStyle: "long" }), by: by ?? "" }) : t("term.open"));
    state.dataset.closed = String(closed);
    close.hidden = closed;
    confirm.hidden = true;
  }
  showState(course.closedAt, course.closedBy);
  close.addEventListener("click", () => {
    confirm.hidden = false;
    setText(out, t("term.closeWarning"));
    confirm.focus();
  });
  confirm.addEventListener("click", async () => {
    confirm.disabled = true;
    try {
      const closed = await api.closeCourse(course.name);
      showState(closed.closedAt, closed.closedBy);
      setText(out, "");
      announce(t("term.closed"));
    } catch (err) {
      setText(out, err.message);
    } finally {
      confirm.disabled = false;
    }
  });

  const name = h("input", { id: "copy-name", name: "name", maxlength: "64", required: true, autocomplete: "off", autocapitalize: "none" });
  const title = h("input", { id: "copy-title", name: "title", maxlength: "200", value: course.title, autocomplete: "off" });
  const starts = h("input", { id: "copy-starts", name: "starts", type: "date", required: true });
  const copy = h("button", { type: "submit", class: "primary", id: "copy-submit" }, t("term.copy"));
  const report = h("div", { id: "copy-report", role: "status" });
  const form = h(
    "form",
    { id: "copy-form", novalidate: true },
    h("h4", null, t("term.copyHeading")),
    h("p", { class: "muted" }, t("term.copyHelp")),
    h("div", { class: "field" }, h("label", { for: "copy-name" }, t("courses.name")), name),
    h("div", { class: "field" }, h("label", { for: "copy-title" }, t("courses.titleLabel")), title),
    h("div", { class: "field" }, h("label", { for: "copy-starts" }, t("term.starts")), starts),
    copy,
    report,
  );
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    report.replaceChildren();
    if (!name.value.trim() || !starts.value) {
      setText(report, t("term.copyMissing"));
      (name.value.trim() ? starts : name).focus();
      return;
    }
    copy.disabled = true;
    try {
      const spec = { name: name.value.trim(), title: title.value.trim() || course.title, starts: starts.value };
      const made = await api.copyCourse(course.name, spec);
      const link = h("a", { href: `#/courses?course=${encodeURIComponent(made.course.name)}`, id: "copy-link" }, made.course.title);
      /** @type {HTMLElement[]} */
      const lines = [h("p", { id: "copy-summary" }, t("term.copied", { assignments: made.assignments, bookings: made.bookings, days: made.shiftDays }), " ", link)];
      if (made.skippedBookings.length > 0) {
        lines.push(
          h("p", null, t("term.skipped", { count: made.skippedBookings.length })),
          h(
            "ul",
            { id: "copy-skipped" },
            made.skippedBookings.map((/** @type {any} */ s) => h("li", null, formatDateTime(new Date(s.startsAt), { dateStyle: "full", timeStyle: "short" }))),
          ),
        );
      }
      report.replaceChildren(...lines);
      announce(t("term.copiedShort", { course: made.course.title }));
    } catch (err) {
      setText(report, err.message);
    } finally {
      copy.disabled = false;
    }
  });

  return h(
    "section",
    { id: "term", "data-course": course.name },
    h("h3", null, t("term.heading")),
    state,
    h("p", { class: "muted" }, t("term.closeHelp")),
    h("p", null, close, " ", confirm),
    out,
    form,
    ctx.user?.admin ? h("p", { class: "muted" }, t("term.adminHelp")) : "",
  );
}
