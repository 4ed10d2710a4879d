// @ts-check
// Reading a run's samples.csv (header line, then numbers; `t,u,y` first).

import { t } from "./i18n.js";

/**
 * Parse a numeric CSV into named columns. A `k` column that the file does not
 * have is the row index (a run's CSV starts at sample 0). Lines starting with
 * `#` are comments; empty cells and non-numbers become NaN.
 * @param {string} text
 * @param {string[]} wanted column names to return
 * @returns {Record<string, Float64Array>}
 */
export function parseCsv(text, wanted) {
  const lines = text.split(/\r?\n/).filter((l) => l.trim() !== "" && !l.startsWith("#"));
  if (lines.length === 0) throw new Error(t("csv.empty"));
  const header = lines[0].split(",").map((s) => s.trim().toLowerCase());
  const rows = lines.length - 1;
  /** @type {Record<string, Float64Array>} */
  const out = {};
  for (const name of wanted) {
    const col = header.indexOf(name);
    const arr = new Float64Array(rows);
    if (col === -1) {
      if (name !== "k") throw new Error(t("csv.noColumn", { column: JSON.stringify(name), columns: header.join(", ") }));
      for (let i = 0; i < rows; i += 1) arr[i] = i;
    } else {
      for (let i = 0; i < rows; i += 1) {
        const cell = lines[i + 1].split(",")[col];
        const v = cell === undefined || cell.trim() === "" ? Number.NaN : Number(cell);
        arr[i] = Number.isFinite(v) ? v : Number.NaN;
      }
    }
    out[name] = arr;
  }
  return out;
}
