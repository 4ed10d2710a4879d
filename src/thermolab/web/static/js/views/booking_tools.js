// @ts-check
// The calendar page's tools (issue #24, item 7): a course's weekly quota of
// students' own bookings (teachers), a student's booking of a free slot for
// themselves, the secret calendar-feed addresses a calendar application
// subscribes to (shown once, revocable), and e-mail reminders where the lab
// has a mail server. Each is a card of its own under the calendar.

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { formatDateTime, formatNumber, t } from "../i18n.js";

/** @param {Date} d  as an <input type="date"> value (local) */
export function dateValue(d) {
  const pad = (/** @type {number} */ n) => String(n).padStart(2, "0");
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}`;
}

/** @param {string} id @param {string} label @param {HTMLElement} input */
const field = (id, label, input) => h("div", { class: "field" }, h("label", { for: id }, label), input);

/**
 * Teachers: how many minutes a week each student of a course may book for themselves.
 * @param {Array<{name: string, title: string}>} courses
 */
export function quotaCard(courses) {
  const status = h("p", { class: "muted", role: "status", id: "quota-status" });
  const course = h("select", { id: "quota-course" }, ...courses.map((c) => h("option", { value: c.name }, `${c.title} (${c.name})`)));
  const minutes = h("input", { id: "quota-minutes", type: "number", min: "0", max: "10080", step: "15", inputmode: "numeric" });
  const save = h("button", { type: "submit", id: "quota-save" }, t("calendar.quotaSave"));
  const load = () =>
    api
      .bookingQuota(course.value)
      .then((q) => {
        if (q.course !== course.value) return; // another course was chosen meanwhile
        minutes.value = String(q.minutesPerWeek);
        minutes.dataset.course = q.course; // loaded (what a test waits for)
      })
      .catch((err) => setText(status, err.message));
  course.addEventListener("change", () => void load());
  const el = h(
    "form",
    { class: "card", id: "quota-form" },
    h("h2", null, t("calendar.quotaHeading")),
    h("p", { class: "muted" }, t("calendar.quotaHelp")),
    field("quota-course", t("calendar.courseLabel"), course),
    field("quota-minutes", t("calendar.quotaMinutes"), minutes),
    h("div", { class: "buttons" }, save),
    status,
  );
  el.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    try {
      const q = await api.setBookingQuota(course.value, Number(minutes.value));
      setText(status, t("calendar.quotaSaved", { minutes: formatNumber(q.minutesPerWeek) }));
    } catch (err) {
      setText(status, err.message);
    }
  });
  if (courses.length) void load();
  return el;
}

/**
 * Students: book a free slot of a course's rig for themselves, within its weekly quota.
 * @param {Array<any>} courses  GET /api/own-bookings
 * @param {(from: Date) => void} booked  called with the new slot's start
 */
export function ownBookingCard(courses, booked) {
  const error = h("p", { class: "error", id: "own-error", role: "alert" });
  const left = h("p", { class: "muted", id: "own-left" });
  const course = h("select", { id: "own-course" }, ...courses.map((c) => h("option", { value: c.course }, c.title)));
  const rig = h("select", { id: "own-rig" });
  const date = h("input", { id: "own-date", type: "date", required: true, value: dateValue(new Date()) });
  const start = h("input", { id: "own-start", type: "time", required: true });
  const end = h("input", { id: "own-end", type: "time", required: true });
  const chosen = () => courses.find((c) => c.course === course.value) ?? courses[0];
  const show = () => {
    const c = chosen();
    rig.replaceChildren(...c.rigs.map((/** @type {string} */ r) => h("option", { value: r }, r)));
    setText(left, t("calendar.ownLeft", { used: formatNumber(c.usedMinutes), quota: formatNumber(c.minutesPerWeek) }));
  };
  course.addEventListener("change", show);
  show();
  const el = h(
    "form",
    { class: "card", id: "own-form", novalidate: true, "aria-describedby": "own-error own-left" },
    h("h2", null, t("calendar.ownHeading")),
    left,
    field("own-course", t("calendar.courseLabel"), course),
    field("own-rig", t("calendar.rigLabel"), rig),
    field("own-date", t("calendar.date"), date),
    field("own-start", t("calendar.start"), start),
    field("own-end", t("calendar.end"), end),
    error,
    h("div", { class: "buttons" }, h("button", { type: "submit", class: "primary", id: "own-submit" }, t("calendar.ownBook"))),
  );
  el.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setText(error, "");
    if (!date.value || !start.value || !end.value) {
      setText(error, t("calendar.missing"));
      return;
    }
    const from = new Date(`${date.value}T${start.value}`);
    const to = new Date(`${date.value}T${end.value}`); // never moved to the next day
    try {
      await api.bookOwn(chosen().course, { rig: rig.value, startsAt: from.toISOString(), endsAt: to.toISOString() });
      announce(t("calendar.booked"));
      const fresh = await api.ownBookingCourses();
      courses.splice(0, courses.length, ...fresh);
      show();
      booked(from);
    } catch (err) {
      setText(error, err.message);
    }
  });
  return el;
}

/**
 * Everyone: secret calendar addresses (all my courses, or one), shown once, revocable.
 * @param {Array<{name: string, title: string}>} courses  a teacher's; [] for a student
 */
export function feedsCard(courses) {
  const status = h("p", { class: "muted", role: "status", id: "feed-status" });
  const list = h("ul", { id: "feed-list" });
  const which = h("select", { id: "feed-course" }, h("option", { value: "" }, t("calendar.feedAll")), ...courses.map((c) => h("option", { value: c.name }, c.title)));
  const address = h("input", { id: "feed-url", type: "url", readonly: true, hidden: true, "aria-label": t("calendar.feedUrl") });
  const refresh = () =>
    api
      .calendarFeeds()
      .then((feeds) =>
        list.replaceChildren(
          ...feeds.map((/** @type {any} */ f) => {
            const label = t("calendar.feedItem", { what: f.course ?? t("calendar.feedAll"), date: formatDateTime(new Date(f.createdAt), { dateStyle: "medium" }) });
            return h(
              "li",
              { "data-testid": "feed" },
              label,
              " ",
              h("button", { type: "button", class: "link-button", "aria-label": t("calendar.feedRevokeOne", { feed: label }), onclick: () => void revoke(f.id) }, t("calendar.feedRevoke")),
            );
          }),
        ),
      )
      .catch((err) => setText(status, err.message));
  /** @param {number} id */
  async function revoke(id) {
    try {
      await api.revokeCalendarFeed(id);
      address.hidden = true;
      announce(t("calendar.feedRevoked"));
      await refresh();
    } catch (err) {
      setText(status, err.message);
    }
  }
  const create = h("button", { type: "button", id: "feed-create" }, t("calendar.feedCreate"));
  create.addEventListener("click", async () => {
    try {
      const made = await api.createCalendarFeed(which.value || null);
      address.value = made.url;
      address.hidden = false;
      address.focus();
      address.select();
      setText(status, t("calendar.feedShownOnce"));
      await refresh();
    } catch (err) {
      setText(status, err.message);
    }
  });
  void refresh();
  return h(
    "section",
    { class: "card", id: "feeds", "aria-labelledby": "feeds-heading" },
    h("h2", { id: "feeds-heading" }, t("calendar.feedHeading")),
    h("p", { class: "muted" }, t("calendar.feedHelp")),
    field("feed-course", t("calendar.feedWhich"), which),
    h("div", { class: "buttons" }, create),
    address,
    status,
    list,
  );
}

/** Everyone: an e-mail reminder so many minutes before each booking (where the lab can send). */
export function remindersCard() {
  const status = h("p", { class: "muted", role: "status", id: "reminder-status" });
  const email = h("input", { id: "reminder-email", type: "email", autocomplete: "email", maxlength: "254" });
  const minutes = h("input", { id: "reminder-minutes", type: "number", min: "1", max: "10080", value: "60", inputmode: "numeric" });
  const stop = h("button", { type: "button", id: "reminder-stop" }, t("calendar.reminderStop"));
  const form = h(
    "form",
    { id: "reminder-form", hidden: true },
    field("reminder-email", t("calendar.reminderEmail"), email),
    field("reminder-minutes", t("calendar.reminderMinutes"), minutes),
    h("div", { class: "buttons" }, h("button", { type: "submit", id: "reminder-save" }, t("calendar.reminderSave")), stop),
  );
  const card = h("section", { class: "card", id: "reminders", "aria-labelledby": "reminders-heading" }, h("h2", { id: "reminders-heading" }, t("calendar.reminderHeading")), form, status);
  api
    .reminders()
    .then((r) => {
      if (!r.available) {
        setText(status, t("calendar.reminderUnavailable"));
        return;
      }
      form.hidden = false;
      if (r.email) {
        email.value = r.email;
        minutes.value = String(r.minutesBefore);
      }
    })
    .catch((err) => setText(status, err.message));
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    try {
      const r = await api.setReminders(email.value.trim(), Number(minutes.value));
      setText(status, t("calendar.reminderSaved", { email: r.email, minutes: formatNumber(r.minutesBefore) }));
    } catch (err) {
      setText(status, err.message);
    }
  });
  stop.addEventListener("click", async () => {
    try {
      await api.stopReminders();
      email.value = "";
      setText(status, t("calendar.reminderStopped"));
    } catch (err) {
      setText(status, err.message);
    }
  });
  return card;
}
