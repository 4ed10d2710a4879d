// @ts-check
// The calendar of bookings, a week at a time: each day's slots with their
// times in the reader's zone and language, the course (a student sees other
// courses' slots only as reserved) and the rigs. A teacher books a slot for a
// course on one or more rigs, edits or cancels it; a slot that overlaps
// another is refused by the server (409 booking_clash), and the page says
// which slot is in the way. Laid out as a list of days, so it reads on a phone.
// A slot ends on the day its end date says, never moved past midnight by
// itself: swapped times are refused (422 slot_ends_before_start), and longer
// than a day needs the teacher's "longer" box. A teacher may repeat the slot
// weekly until a day; the weeks in the way are listed. The tools under the
// calendar (quota, own bookings, feeds, reminders) are ./booking_tools.js.

import { api } from "../api.js";
import { announce, h, setText } from "../dom.js";
import { formatDateTime, formatNumber, t } from "../i18n.js";
import { rigTitle } from "../shapes.js";
import { dateValue, feedsCard, ownBookingCard, quotaCard, remindersCard } from "./booking_tools.js";

const DAY_MS = 24 * 3600 * 1000;

/** Midnight (local) of the Monday of the week holding `date`. */
export function weekStart(date) {
  const d = new Date(date.getFullYear(), date.getMonth(), date.getDate());
  const back = (d.getDay() + 6) % 7; // Monday = 0
  d.setDate(d.getDate() - back);
  return d;
}

/** @param {Date} d  as an <input type="time"> value (local) */
function timeValue(d) {
  return `${String(d.getHours()).padStart(2, "0")}:${String(d.getMinutes()).padStart(2, "0")}`;
}

/** @param {Date} d */
const hhmm = (d) => formatDateTime(d, { timeStyle: "short" });

/**
 * @param {HTMLElement} main
 * @param {{query: URLSearchParams}} _route
 * @param {any} ctx
 */
export function mount(main, _route, ctx) {
  const teacher = ctx.user?.role === "teacher";
  let alive = true;
  let monday = weekStart(new Date());
  /** @type {number | null} the booking being edited */
  let editing = null;

  const status = h("p", { class: "muted", role: "status", id: "calendar-status" });
  const weekLabel = h("h2", { id: "week-label" });
  const days = h("div", { id: "calendar-days", class: "calendar-days" });
  const prev = h("button", { type: "button", id: "week-prev" }, t("calendar.previous"));
  const next = h("button", { type: "button", id: "week-next" }, t("calendar.next"));
  const today = h("button", { type: "button", id: "week-today" }, t("calendar.thisWeek"));
  const zone = Intl.DateTimeFormat().resolvedOptions().timeZone;

  main.append(
    h("h1", null, t("calendar.title")),
    h("p", { class: "lede" }, t("calendar.lede", { zone })),
    h("div", { class: "buttons calendar-nav" }, prev, today, next),
    weekLabel,
    status,
    days,
  );

  const form = teacher ? bookingForm() : null;
  if (form) main.append(form.el);
  const tools = h("div", { id: "booking-tools" });
  main.append(tools);
  (teacher ? api.courses() : api.ownBookingCourses())
    .then((/** @type {any[]} */ found) => {
      if (!alive) return;
      if (teacher) tools.append(quotaCard(found), feedsCard(found), remindersCard());
      else {
        if (found.length) {
          tools.append(
            ownBookingCard(found, (from) => {
              monday = weekStart(from);
              void refresh();
            }),
          );
        }
        tools.append(feedsCard([]), remindersCard());
      }
    })
    .catch((err) => setText(status, err.message));

  async function refresh() {
    const end = new Date(monday.getTime() + 7 * DAY_MS + 3600 * 1000); // a DST week has 169 h
    setText(weekLabel, t("calendar.week", { date: formatDateTime(monday, { dateStyle: "long" }) }));
    let slots;
    try {
      slots = await api.bookings(monday.toISOString(), end.toISOString());
    } catch (err) {
      setText(status, err.message);
      return;
    }
    if (!alive) return;
    setText(status, "");
    const sections = [];
    for (let i = 0; i < 7; i++) {
      const day = new Date(monday.getFullYear(), monday.getMonth(), monday.getDate() + i);
      const after = new Date(day.getFullYear(), day.getMonth(), day.getDate() + 1);
      const those = slots.filter((b) => new Date(b.startsAt) < after && new Date(b.endsAt) > day);
      const heading = formatDateTime(day, { weekday: "long", day: "numeric", month: "long" });
      sections.push(
        h(
          "section",
          { class: "calendar-day", "aria-label": heading },
          h("h3", null, heading),
          those.length === 0
            ? h("p", { class: "muted" }, t("calendar.free"))
            : h("ul", { class: "slots" }, ...those.map(slotItem)),
        ),
      );
    }
    days.replaceChildren(...sections);
  }

  /** @param {any} b */
  function slotItem(b) {
    const start = new Date(b.startsAt);
    const end = new Date(b.endsAt);
    const who = b.course ? t("calendar.course", { course: b.courseTitle ?? b.course }) : t("calendar.reserved");
    const item = h(
      "li",
      { class: "slot", "data-own": b.own ? "true" : "false", "data-testid": "slot", "data-booking": b.id },
      h("strong", null, t("calendar.times", { start: hhmm(start), end: hhmm(end) })),
      " ",
      who,
      " · ",
      t("calendar.rigs", { rigs: b.rigs.join(", ") }),
      b.note ? ` · ${b.note}` : "",
    );
    if (!teacher && b.mine) {
      const label = t("calendar.times", { start: hhmm(start), end: hhmm(end) });
      item.append(
        " ",
        h("button", { type: "button", class: "link-button", "aria-label": t("calendar.cancelSlot", { slot: label }), onclick: () => void cancel(b.id) }, t("calendar.cancel")),
      );
    }
    if (teacher) {
      const label = t("calendar.times", { start: hhmm(start), end: hhmm(end) });
      item.append(
        " ",
        h("button", { type: "button", class: "link-button", "aria-label": t("calendar.editSlot", { slot: label }), onclick: () => form?.edit(b) }, t("calendar.edit")),
        " ",
        h("button", { type: "button", class: "link-button", "aria-label": t("calendar.cancelSlot", { slot: label }), onclick: () => void cancel(b.id) }, t("calendar.cancel")),
      );
    }
    return item;
  }

  /** @param {number} id */
  async function cancel(id) {
    try {
      await api.cancelBooking(id);
      announce(t("calendar.cancelled"));
      if (editing === id) form?.reset();
      await refresh();
    } catch (err) {
      setText(status, err.message);
    }
  }

  function bookingForm() {
    const error = h("p", { class: "error", id: "booking-error", role: "alert" });
    const course = h("select", { id: "booking-course", required: true });
    const rigs = h("fieldset", { id: "booking-rigs" }, h("legend", null, t("calendar.rigsLabel")));
    const date = h("input", { id: "booking-date", type: "date", required: true, value: dateValue(new Date()) });
    const start = h("input", { id: "booking-start", type: "time", required: true, value: "08:00" });
    const end = h("input", { id: "booking-end", type: "time", required: true, value: "10:00" });
    const endDate = h("input", { id: "booking-end-date", type: "date", required: true, value: dateValue(new Date()) });
    const longer = h("input", { id: "booking-longer", type: "checkbox" });
    const until = h("input", { id: "booking-repeat-until", type: "date" });
    const skip = h("input", { id: "booking-skip-clashes", type: "checkbox" });
    // The end's day follows the start's until the teacher changes it.
    date.addEventListener("change", () => {
      endDate.value = date.value;
    });
    const note = h("input", { id: "booking-note", maxlength: "200", autocomplete: "off" });
    const heading = h("h2", null, t("calendar.bookHeading"));
    const submit = h("button", { type: "submit", class: "primary", id: "booking-submit" }, t("calendar.book"));
    const stop = h("button", { type: "button", id: "booking-stop-edit", hidden: true }, t("calendar.stopEditing"));
    const el = h(
      "form",
      { class: "card", id: "booking-form", novalidate: true, "aria-describedby": "booking-error" },
      heading,
      h("div", { class: "field" }, h("label", { for: "booking-course" }, t("calendar.courseLabel")), course),
      rigs,
      h("div", { class: "field" }, h("label", { for: "booking-date" }, t("calendar.date")), date),
      h("div", { class: "field" }, h("label", { for: "booking-start" }, t("calendar.start")), start),
      h("div", { class: "field" }, h("label", { for: "booking-end-date" }, t("calendar.endDate")), endDate),
      h("div", { class: "field" }, h("label", { for: "booking-end" }, t("calendar.end")), end),
      h("div", { class: "field check" }, longer, h("label", { for: "booking-longer" }, t("calendar.longer"))),
      h("div", { class: "field", id: "booking-repeat" }, h("label", { for: "booking-repeat-until" }, t("calendar.repeatUntil")), until),
      h("div", { class: "field check" }, skip, h("label", { for: "booking-skip-clashes" }, t("calendar.skipClashes"))),
      h("div", { class: "field" }, h("label", { for: "booking-note" }, t("calendar.note")), note),
      error,
      h("div", { class: "buttons" }, submit, stop),
    );

    Promise.all([api.courses(), api.rigs()])
      .then(([courses, all]) => {
        if (!alive) return;
        course.replaceChildren(...courses.map((c) => h("option", { value: c.name }, `${c.title} (${c.name})`)));
        const list = Array.isArray(all) ? all : (all?.rigs ?? []);
        rigs.append(
          ...list.map((r) =>
            h(
              "div",
              { class: "field check" },
              h("input", { type: "checkbox", id: `booking-rig-${r.id}`, value: r.id }),
              h("label", { for: `booking-rig-${r.id}` }, rigTitle(r)),
            ),
          ),
        );
      })
      .catch((err) => setText(error, err.message));

    /** @returns {HTMLInputElement[]} */
    const boxes = () => [...rigs.querySelectorAll("input[type=checkbox]")].map((b) => /** @type {HTMLInputElement} */ (b));

    el.addEventListener("submit", async (ev) => {
      ev.preventDefault();
      setText(error, "");
      const chosen = boxes().filter((b) => b.checked).map((b) => b.value);
      if (!course.value || chosen.length === 0 || !date.value || !start.value || !end.value) {
        setText(error, t("calendar.missing"));
        return;
      }
      const from = new Date(`${date.value}T${start.value}`);
      // The end as typed: a reversed slot is refused by the server, never moved a day on.
      const to = new Date(`${endDate.value || date.value}T${end.value}`);
      const spec = { rigs: chosen, startsAt: from.toISOString(), endsAt: to.toISOString(), note: note.value.trim(), longer: longer.checked };
      submit.disabled = true;
      try {
        if (editing === null && until.value) {
          // The weeks keep this wall-clock time in the reader's zone across daylight saving.
          const series = await api.bookSeries({ course: course.value, ...spec, until: until.value, skipClashes: skip.checked, zone: zone || undefined });
          announce(t("calendar.seriesBooked", { booked: formatNumber(series.booked.length), skipped: formatNumber(series.skipped.length) }));
          setText(error, series.skipped.length ? t("calendar.seriesSkipped", { weeks: clashDays(series.skipped) }) : "");
        } else if (editing === null) await api.book({ course: course.value, ...spec });
        else await api.editBooking(editing, spec);
        if (editing !== null || !until.value) announce(t(editing === null ? "calendar.booked" : "calendar.saved"));
        const said = error.textContent;
        reset();
        setText(error, said ?? "");
        monday = weekStart(from);
        await refresh();
      } catch (err) {
        const clashes = err?.body?.clashes;
        setText(error, Array.isArray(clashes) ? `${err.message} ${t("calendar.seriesClashes", { weeks: clashDays(clashes) })}` : err.message);
      } finally {
        submit.disabled = false;
      }
    });

    function reset() {
      editing = null;
      course.disabled = false;
      stop.hidden = true;
      setText(heading, t("calendar.bookHeading"));
      setText(submit, t("calendar.book"));
      setText(error, "");
    }

    /** @param {any} b */
    function edit(b) {
      editing = b.id;
      const from = new Date(b.startsAt);
      if (b.course) course.value = b.course;
      course.disabled = true; // a booking keeps its course
      for (const box of boxes()) box.checked = b.rigs.includes(box.value);
      date.value = dateValue(from);
      endDate.value = dateValue(new Date(b.endsAt));
      start.value = timeValue(from);
      end.value = timeValue(new Date(b.endsAt));
      until.value = "";
      note.value = b.note ?? "";
      stop.hidden = false;
      setText(heading, t("calendar.editHeading"));
      setText(submit, t("calendar.save"));
      date.focus();
    }

    stop.addEventListener("click", reset);
    return { el, edit, reset };
  }

  /** @param {Array<any>} weeks  occurrences of a series: their days, in the reader's words */
  function clashDays(weeks) {
    return weeks.map((w) => formatDateTime(new Date(w.startsAt), { dateStyle: "medium", timeStyle: "short" })).join("; ");
  }

  const move = (/** @type {number} */ weeks) => {
    monday = new Date(monday.getFullYear(), monday.getMonth(), monday.getDate() + 7 * weeks);
    void refresh();
  };
  prev.addEventListener("click", () => move(-1));
  next.addEventListener("click", () => move(1));
  today.addEventListener("click", () => {
    monday = weekStart(new Date());
    void refresh();
  });
  void refresh();
  return () => {
    alive = false;
  };
}
