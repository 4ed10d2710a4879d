// The part of uPlot's API that ThermoLab uses, for type-checking only (tsc
// reads this file instead of the vendored uPlot.esm.js; browsers never load it).
// Written for this lab from uPlot's documented options, not taken from uPlot.

declare namespace uPlot {
  interface Series {
    label?: string;
    stroke?: string;
    width?: number;
    dash?: number[];
    points?: { show?: boolean };
    spanGaps?: boolean;
    auto?: boolean;
    /** How the series is drawn (uPlot.paths.bars(...) for a bar chart). */
    paths?: unknown;
    fill?: string;
  }
  interface Axis {
    label?: string;
    size?: number;
    labelSize?: number;
    /** Tick labels: (plot, tick values, axis index, space, tick spacing) -> texts. */
    values?: (u: uPlot, splits: number[], axisIdx: number, space: number, incr: number) => string[];
    /** Where the ticks go: (plot, axis index, min, max) -> tick values. */
    splits?: (u: uPlot, axisIdx: number, min: number, max: number) => number[];
  }
  interface Scale {
    time?: boolean;
    min?: number;
    max?: number;
    /** The scale's range: (plot, data min, data max) -> [min, max]. */
    range?: (u: uPlot, min: number, max: number) => [number, number];
  }
  interface Options {
    width: number;
    height: number;
    series: Series[];
    scales?: Record<string, Scale>;
    axes?: Axis[];
    legend?: { show?: boolean; live?: boolean };
    cursor?: { drag?: { x?: boolean; y?: boolean } };
    hooks?: { draw?: Array<(u: uPlot) => void> };
  }
  type AlignedData = ArrayLike<number | null>[];
}

declare class uPlot {
  constructor(opts: uPlot.Options, data: uPlot.AlignedData, target: HTMLElement);
  readonly width: number;
  readonly height: number;
  readonly scales: Record<string, { min: number; max: number }>;
  setData(data: uPlot.AlignedData, resetScales?: boolean): void;
  setSize(size: { width: number; height: number }): void;
  destroy(): void;
  /** Path builders; `bars({size: [fraction of the slot, max px], align: -1 | 0 | 1})`. */
  static paths: { bars?: (opts: { size?: [number, number]; align?: -1 | 0 | 1 }) => unknown };
}

export default uPlot;
