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
  }
  interface Axis {
    label?: string;
    size?: number;
    labelSize?: number;
    /** Tick labels: (plot, tick values, axis index, space, tick spacing) -> texts. */
    values?: (u: uPlot, splits: number[], axisIdx: number, space: number, incr: number) => string[];
  }
  interface Scale {
    time?: boolean;
    min?: number;
    max?: number;
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
}

export default uPlot;
