// @ts-check
// Charts on uPlot, redrawn at most REDRAWS_PER_SECOND times a second.
//
// Data arrive at up to 10 samples/s on a real rig, faster on a sped-up twin (the
// quick start's runs 60 samples/s), and in bursts of thousands when a gap is
// replayed; each arrival only marks the chart dirty. The next animation frame,
// once a tenth of a second has passed since the last redraw, pulls the current
// data from the chart's `source` (zero-copy ring-buffer views) and redraws once:
// a real rig's every sample still shows as it comes, and a phone following a
// twin at 60 samples/s redraws 10 times a second, not 60. A hidden tab gets no
// frames, so it does no drawing at all, and catches up with one redraw when
// shown again.
//
// Every chart has a data-table alternative (WCAG 1.1.1 / 1.3.1): a toggle
// shows the newest TABLE_ROWS samples it draws as a table with the axis and
// series names as headers, kept current while it is open. A bar chart (one
// bar per named category: a student, a rig) shows every row instead.
//
// A time chart may offer time windows (opts.windows): "last 100 s", "last 500 s"
// and "all", as toggle buttons beside the table toggle. Buttons, not pinch or
// drag zoom: they work the same with a finger, a mouse and the keyboard (Tab,
// Enter), a screen reader says which is pressed (aria-pressed), they do not
// fight the phone's own page scroll and pinch, and the window follows the live
// data (the last 100 s stay the last 100 s as samples arrive), where a drag
// zoom would freeze a fixed range while the run goes on.

import uPlot from "../vendor/uplot/uPlot.esm.js";
import { h } from "./dom.js";
import { formatNumber, t } from "./i18n.js";

/** Colours that stay distinguishable for the common colour-vision deficiencies (Okabe–Ito). */
export const COLORS = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000"];

/**
 * Axis tick labels in the current language's form (decimal comma in pt-BR),
 * each with the decimals the tick spacing needs (uPlot's axis `values` hook).
 * @param {unknown} _plot
 * @param {number[]} splits  the tick values
 * @param {number} _axis
 * @param {number} _space
 * @param {number} incr  the spacing between ticks
 * @returns {string[]}
 */
export function tickLabels(_plot, splits, _axis, _space, incr) {
  const step = String(Number(incr.toPrecision(10)));
  const [mantissa, exponent] = step.split("e");
  const fraction = mantissa.split(".")[1]?.length ?? 0;
  const decimals = Math.min(20, Math.max(0, fraction - Number(exponent ?? 0)));
  return splits.map((v) =>
    formatNumber(v, { minimumFractionDigits: decimals, maximumFractionDigits: decimals, useGrouping: false }),
  );
}

/** How many of the newest samples the table alternative of a chart shows. */
export const TABLE_ROWS = 10;

/** The time windows a time chart offers besides "all" (s): a long square wave's last periods. */
export const TIME_WINDOWS = [100, 500];

/** At most this many redraws a second, whatever the data's rate (see the top). */
export const REDRAWS_PER_SECOND = 10;

/** Narrower than this is a phone (the css's phone layout: max-width 599px): its charts are drawn lower, so more of the page fits the screen. */
const PHONE_WIDTH = 600;
/** The height of a chart that names none: on a phone, and elsewhere. */
const HEIGHT_PHONE = 144;
const HEIGHT = 220;

/**
 * The columns of `data` from the first x at or after `from` on (x ascending);
 * typed arrays as views, without copying.
 * @param {ArrayLike<number>[]} data
 * @param {number} from
 * @returns {ArrayLike<number>[]}
 */
export function fromX(data, from) {
  const x = data[0];
  let lo = 0;
  let hi = x.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (x[mid] < from) lo = mid + 1;
    else hi = mid;
  }
  if (lo === 0) return data;
  return data.map((col) => (ArrayBuffer.isView(col) ? /** @type {Float64Array} */ (col).subarray(lo) : Array.prototype.slice.call(col, lo)));
}

export class Chart {
  /**
   * @param {HTMLElement} parent
   * @param {object} opts
   * @param {string} opts.label       accessible name of the chart
   * @param {string} opts.xLabel
   * @param {string} opts.yLabel
   * @param {{label: string, color?: string, dash?: number[], width?: number, points?: boolean,
   *   auto?: boolean}[]} opts.series  `auto: false` keeps a series (NaN where it has no value)
   *   out of the axis range
   * @param {() => ArrayLike<number>[]} opts.source   [x, y1, y2...] for the next draw
   * @param {number} [opts.height]
   * @param {number[]} [opts.windows] time windows (seconds of x) offered beside "all": the
   *   chart then shows the newest that many seconds of its data
   * @param {(seconds: number | null) => void} [opts.onWindow] called when the reader picks a window
   * @param {string} [opts.description] longer text for screen readers
   * @param {string} [opts.emptyText] what the chart says while it has no data
   * @param {string[]} [opts.categories] a bar chart: x is the index of these names (at most two
   *   series, side by side); its table shows every row, named
   */
  constructor(parent, opts) {
    this._source = opts.source;
    this._categories = opts.categories ?? null;
    this._raf = 0;
    this._wait = 0; // a timer until the next redraw may be asked for
    this._drawnAt = -Infinity;
    this._destroyed = false;
    const descId = `chart-desc-${Math.random().toString(36).slice(2)}`;
    this.el = h(
      "figure",
      { class: "chart", role: "group", "aria-label": opts.label, "aria-describedby": opts.description ? descId : null },
      opts.description ? h("p", { class: "visually-hidden", id: descId }, opts.description) : null,
    );
    // The axes' labels are drawn on the canvas: said here too, for tests and tools.
    this.el.dataset.xLabel = opts.xLabel;
    this.el.dataset.yLabel = opts.yLabel;
    this._plotHost = h("div", { class: "chart-plot", "aria-hidden": "true" });
    this._emptyNote = h("p", { class: "chart-empty" }, opts.emptyText ?? t("chart.waiting"));
    this._columns = [opts.xLabel, ...opts.series.map((s) => s.label)];
    const tableId = `chart-table-${Math.random().toString(36).slice(2)}`;
    this._tableBody = h("tbody");
    this._table = h(
      "div",
      { class: "table-wrap chart-table", id: tableId, hidden: true, tabindex: "0", role: "region", "aria-label": t("chart.tableOf", { chart: opts.label }) },
      h(
        "table",
        null,
        h("caption", null, this._categories ? t("chart.tableCaptionAll", { chart: opts.label }) : t("chart.tableCaption", { chart: opts.label, count: TABLE_ROWS })),
        h("thead", null, h("tr", null, this._columns.map((c) => h("th", { scope: "col", class: "num" }, c)))),
        this._tableBody,
      ),
    );
    this._tableToggle = h(
      "button",
      { type: "button", class: "link-button chart-toggle", "aria-expanded": "false", "aria-controls": tableId, "data-action": "chart-table" },
      t("chart.showTable"),
    );
    this._tableToggle.addEventListener("click", () => this.showTable(this._table.hidden));
    /** @type {number | null} seconds of x shown (null: all) */
    this.timeWindow = null;
    /** @type {HTMLButtonElement[]} */
    this._windowButtons = [];
    const tools = h("div", { class: "chart-tools" }, this._tableToggle);
    if (opts.windows?.length) {
      tools.append(this._windowGroup(opts.label, opts.windows, opts.onWindow));
      this.el.dataset.window = "all";
    }
    this.el.append(this._plotHost, this._emptyNote, tools, this._table);
    parent.append(this.el);
    const width = Math.max(200, this._plotHost.clientWidth || parent.clientWidth || 320);
    const series = [
      { label: opts.xLabel },
      ...opts.series.map((s, i) => ({
        label: s.label,
        stroke: s.color ?? COLORS[i % COLORS.length],
        width: s.width ?? 1.5,
        dash: s.dash,
        points: { show: s.points ?? false },
        spanGaps: false,
        // uPlot ranges its scales over series marked auto, and a NaN there (a
        // model not identified yet) would spoil the range: such series say auto: false.
        auto: s.auto ?? true,
        ...(this._categories ? barSeries(i, opts.series.length) : {}),
      })),
    ];
    const names = this._categories;
    this.plot = new uPlot(
      {
        width,
        height: opts.height ?? (window.innerWidth < PHONE_WIDTH ? HEIGHT_PHONE : HEIGHT),
        series,
        scales: names
          ? { x: { time: false, range: () => [-0.5, Math.max(0.5, names.length - 0.5)] }, y: { range: (_u, _min, max) => [0, max > 0 ? max * 1.1 : 1] } }
          : { x: { time: false } },
        axes: [
          names
            ? { label: opts.xLabel, size: 50, labelSize: 18, splits: () => names.map((_, i) => i), values: (_u, splits) => splits.map((v) => names[v] ?? "") }
            : { label: opts.xLabel, size: 40, labelSize: 18, values: tickLabels },
          { label: opts.yLabel, size: 60, labelSize: 18, values: tickLabels },
        ],
        legend: { show: true, live: false },
        cursor: { drag: { x: false, y: false } },
        hooks: {
          // The y range drawn: lets a test see that the axis is a real range (a NaN
          // in an auto-ranged series would leave an empty plot with no axis).
          // The x range too: lets a test see the time window drawn.
          draw: [(u) => { this.el.dataset.yRange = `${u.scales.y.min},${u.scales.y.max}`; this.el.dataset.xRange = `${u.scales.x.min},${u.scales.x.max}`; }],
        },
      },
      this._empty(series.length),
      this._plotHost,
    );
    // Follow the width of the page (phones rotate; panels open and close).
    this._ro = new ResizeObserver((entries) => {
      const w = Math.floor(entries[0].contentRect.width);
      if (w > 0 && Math.abs(w - this.plot.width) > 1) this.plot.setSize({ width: w, height: this.plot.height });
    });
    this._ro.observe(this._plotHost);
    this.invalidate();
  }

  _empty(n) {
    return Array.from({ length: n }, () => new Float64Array(0));
  }

  /** Ask for a redraw on the next animation frame (cheap to call at any rate). */
  invalidate() {
    if (this._raf || this._wait || this._destroyed) return;
    const early = this._drawnAt + 1000 / REDRAWS_PER_SECOND - performance.now();
    if (early > 0) {
      this._wait = window.setTimeout(() => {
        this._wait = 0;
        this.invalidate();
      }, early);
      return;
    }
    this._raf = requestAnimationFrame((now) => {
      this._raf = 0;
      if (this._destroyed) return;
      this._drawnAt = now;
      this.draw();
    });
  }

  /**
   * The window buttons: one per choice, then "all" (pressed at first).
   * @param {string} label
   * @param {number[]} choices
   * @param {((seconds: number | null) => void) | undefined} onWindow
   */
  _windowGroup(label, choices, onWindow) {
    const group = h("div", { class: "chart-window", role: "group", "aria-label": t("chart.windowOf", { chart: label }) });
    for (const seconds of [...choices, null]) {
      const button = h(
        "button",
        { type: "button", "aria-pressed": String(seconds === null), "data-window": seconds === null ? "all" : String(seconds) },
        seconds === null ? t("chart.windowAll") : t("chart.windowLast", { seconds }),
      );
      button.addEventListener("click", () => {
        this.setWindow(seconds);
        onWindow?.(seconds);
      });
      group.append(button);
      this._windowButtons.push(button);
    }
    return group;
  }

  /**
   * Show only the newest `seconds` of x (null: all of it); kept as data arrive.
   * @param {number | null} seconds
   */
  setWindow(seconds) {
    this.timeWindow = seconds;
    this.el.dataset.window = seconds === null ? "all" : String(seconds);
    for (const b of this._windowButtons) b.setAttribute("aria-pressed", String(b.dataset.window === this.el.dataset.window));
    this.invalidate();
  }

  /** Redraw now from the source. */
  draw() {
    let data = this._source();
    const x = data[0];
    if (this.timeWindow !== null && x.length > 0) data = fromX(data, x[x.length - 1] - this.timeWindow);
    this._emptyNote.hidden = data[0].length > 0;
    this.plot.setData(data, true);
    // How many points are drawn: lets a test see that the window stays bounded.
    this.el.dataset.points = String(data[0].length);
    if (!this._table.hidden) this._fillTable(data);
  }

  /** Show (true) or hide the table of the newest samples. */
  showTable(show) {
    this._table.hidden = !show;
    this._tableToggle.setAttribute("aria-expanded", String(show));
    this._tableToggle.textContent = show ? t("chart.hideTable") : t("chart.showTable");
    if (show) this._fillTable(this._source());
  }

  /** @param {ArrayLike<number>[]} data */
  _fillTable(data) {
    const n = data[0].length;
    const rows = [];
    const names = this._categories;
    for (let i = names ? 0 : Math.max(0, n - TABLE_ROWS); i < n; i++) {
      rows.push(
        h(
          "tr",
          null,
          this._columns.map((_, c) => {
            if (names && c === 0) return h("th", { scope: "row" }, names[i] ?? "");
            const v = data[c]?.[i];
            return h("td", { class: "num" }, typeof v === "number" && Number.isFinite(v) ? formatNumber(v, { maximumSignificantDigits: 6 }) : "–");
          }),
        ),
      );
    }
    this._tableBody.replaceChildren(...rows);
  }

  destroy() {
    this._destroyed = true;
    if (this._raf) cancelAnimationFrame(this._raf);
    if (this._wait) clearTimeout(this._wait);
    this._ro.disconnect();
    this.plot.destroy();
    this.el.remove();
  }
}

/**
 * uPlot's bar paths for series `i` of `n` (one bar centred, two side by side).
 * @param {number} i
 * @param {number} n
 */
function barSeries(i, n) {
  return {
    paths: uPlot.paths.bars?.({ size: [n > 1 ? 0.4 : 0.6, 80], align: n > 1 ? (i === 0 ? -1 : 1) : 0 }),
    fill: COLORS[i % COLORS.length],
    points: { show: false },
  };
}
