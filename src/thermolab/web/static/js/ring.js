// @ts-check
// Fixed-size buffers for live series: memory is allocated once, so a page left
// open for hours holds the same amount as after one minute.

/**
 * A ring buffer of `capacity` rows over named numeric columns.
 *
 * Each column is a Float64Array of twice the capacity and every value is written
 * twice (at i and i + capacity), so the rows in time order are always one
 * contiguous slice: `column(name)` is a zero-copy subarray that uPlot can draw
 * directly, and push() is O(1) with no allocation.
 */
export class RingBuffer {
  /**
   * @param {number} capacity rows kept (the newest ones)
   * @param {string[]} names column names
   */
  constructor(capacity, names) {
    if (!Number.isInteger(capacity) || capacity < 1) {
      throw new RangeError(`capacity must be a positive integer, got ${capacity}`);
    }
    if (!Array.isArray(names) || names.length === 0) {
      throw new RangeError("a ring buffer needs at least one column name");
    }
    this.capacity = capacity;
    this.names = [...names];
    /** @type {Map<string, Float64Array>} */
    this._cols = new Map(names.map((n) => [n, new Float64Array(2 * capacity)]));
    this._next = 0; // slot the next row goes to
    this.length = 0;
  }

  /** Append one row; `row[name]` missing or not a number is stored as NaN. */
  push(row) {
    const i = this._next;
    const j = i + this.capacity;
    for (const [name, col] of this._cols) {
      const v = row[name];
      const x = typeof v === "number" ? v : Number.NaN;
      col[i] = x;
      col[j] = x;
    }
    this._next = i + 1 === this.capacity ? 0 : i + 1;
    if (this.length < this.capacity) this.length += 1;
  }

  /** The start of the time-ordered slice inside each doubled column. */
  _start() {
    const s = this._next - this.length;
    return s < 0 ? s + this.capacity : s;
  }

  /**
   * The column's rows, oldest first, as a view (no copy). The view is only
   * valid until the next push or clear.
   * @param {string} name
   * @returns {Float64Array}
   */
  column(name) {
    const col = this._cols.get(name);
    if (col === undefined) throw new RangeError(`no column named ${JSON.stringify(name)}`);
    const s = this._start();
    return col.subarray(s, s + this.length);
  }

  /** The value of `name` in the newest row, or NaN when empty. */
  last(name) {
    if (this.length === 0) return Number.NaN;
    const col = this._cols.get(name);
    if (col === undefined) throw new RangeError(`no column named ${JSON.stringify(name)}`);
    const i = this._next === 0 ? this.capacity - 1 : this._next - 1;
    return col[i];
  }

  /** Overwrite the column of the newest `values.length` rows (for a recomputed overlay). */
  setColumn(name, values) {
    const col = this._cols.get(name);
    if (col === undefined) throw new RangeError(`no column named ${JSON.stringify(name)}`);
    const n = Math.min(values.length, this.length);
    const s = this._start();
    for (let r = this.length - n, v = values.length - n; r < this.length; r += 1, v += 1) {
      const p = (s + r) % this.capacity;
      col[p] = values[v];
      col[p + this.capacity] = values[v];
    }
  }

  clear() {
    this._next = 0;
    this.length = 0;
  }
}

/**
 * A bounded buffer for a whole trajectory (Ks(k), Ts(k) from the start of a
 * run): it keeps every `stride`-th row; when full, it drops every other row and
 * doubles the stride. The start of the trajectory (where convergence happens)
 * is always kept, the memory never exceeds `capacity` rows, and the resolution
 * falls by at most half the capacity.
 */
export class DecimatingBuffer {
  /**
   * @param {number} capacity maximum rows (even, at least 4)
   * @param {string[]} names column names
   */
  constructor(capacity, names) {
    if (!Number.isInteger(capacity) || capacity < 4 || capacity % 2 !== 0) {
      throw new RangeError(`capacity must be an even integer of at least 4, got ${capacity}`);
    }
    this.capacity = capacity;
    this.names = [...names];
    /** @type {Map<string, Float64Array>} */
    this._cols = new Map(names.map((n) => [n, new Float64Array(capacity)]));
    this.length = 0;
    this.stride = 1;
    this._seen = 0; // rows offered since the start, kept or not
    /** @type {Record<string, number> | null} */
    this._latest = null;
  }

  push(row) {
    const keep = this._seen % this.stride === 0;
    this._seen += 1;
    this._latest = row;
    if (!keep) return;
    if (this.length === this.capacity) this._halve();
    // After halving, the next kept row must again fall on the (doubled) stride.
    if ((this._seen - 1) % this.stride !== 0) return;
    for (const [name, col] of this._cols) {
      const v = row[name];
      col[this.length] = typeof v === "number" ? v : Number.NaN;
    }
    this.length += 1;
  }

  _halve() {
    for (const col of this._cols.values()) {
      for (let i = 0; i < this.capacity / 2; i += 1) col[i] = col[2 * i];
    }
    this.length = this.capacity / 2;
    this.stride *= 2;
  }

  /**
   * The kept rows plus the newest row offered (so the chart always ends at the
   * current estimate), oldest first. A fresh array: safe to keep.
   * @param {string} name
   */
  column(name) {
    const col = this._cols.get(name);
    if (col === undefined) throw new RangeError(`no column named ${JSON.stringify(name)}`);
    const lastKept = (this._seen - 1) % this.stride === 0;
    const extra = this._latest !== null && !lastKept ? 1 : 0;
    const out = new Float64Array(this.length + extra);
    out.set(col.subarray(0, this.length));
    if (extra) {
      const v = this._latest?.[name];
      out[this.length] = typeof v === "number" ? v : Number.NaN;
    }
    return out;
  }

  clear() {
    this.length = 0;
    this.stride = 1;
    this._seen = 0;
    this._latest = null;
  }
}
