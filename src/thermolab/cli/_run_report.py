"""``thermolab run``'s output: the progress bar while it runs, the summary after.

:class:`Progress` draws a one-line bar on a terminal's standard error;
:func:`summary_table` (each method's Ks and Ts) and, for a closed-loop run,
:func:`closed_loop_figures` and :func:`control_table` print the result as
text; :func:`json_report` is the ``--json`` object.
"""

from __future__ import annotations

import math
import signal as signal_module
import threading
import time
from typing import Any, TextIO

__all__ = [
    "Progress",
    "closed_loop_figures",
    "control_table",
    "json_report",
    "summary_table",
]


def closed_loop_figures(result: Any, loop: Any, model: Any) -> dict[str, Any]:
    """Measured (and, with a model, predicted) overshoot, settling time and IAE."""
    from thermolab.control import (
        predict_record_step,
        rest_warning,
        settling_warning,
        step_metrics,
    )
    from thermolab.errors import InvalidDataError

    figures: dict[str, Any] = {"measured": None, "predicted": None, "note": None}
    r = result.extra["r"]
    try:
        if model is None:
            figures["measured"] = step_metrics(result.t, r, result.y).to_dict()
            return figures
        rig = result.rig
        # The lab's figures come from the same function: one operating point rule.
        measured, predicted = predict_record_step(
            model,
            loop.initial_gains,
            result.t,
            r,
            result.y,
            result.u,
            dt=result.dt,
            u_rest=rig.safe_input,
            u_limits=(rig.input_min, rig.input_max),
            derivative_filter=loop.derivative_filter,
        )
    except InvalidDataError as exc:
        figures["note"] = str(exc)
        return figures
    figures["measured"] = measured.to_dict()
    figures["predicted"] = predicted.metrics.to_dict()
    notes = (
        rest_warning(model, measured, result.t, result.y),
        settling_warning(measured, predicted.metrics),
    )
    figures["note"] = "; ".join(n for n in notes if n) or None
    return figures


def control_table(result: Any, loop: Any, tuning: Any, figures: dict[str, Any]) -> str:
    """The control line (mode, set point, gains, tuning) and the closed-loop figures' table."""
    rig = result.rig
    g = loop.gains
    how = f"  ({tuning.rule} {tuning.form}" if tuning is not None else ""
    if tuning is not None and tuning.tau_c is not None:
        how += f", tau_c {tuning.tau_c:g} s"
    how += ")" if tuning is not None else ""
    lines = [
        f"control: PID {'auto' if loop.auto else 'manual'}   set point {loop.setpoint:g} "
        f"{rig.output_unit}   Kp {g.Kp:.6g}  Ti {g.Ti:.6g} s  Td {g.Td:.6g} s{how}"
    ]
    if loop.tuner is not None:
        lines.append(
            f"adaptive: {loop.tuner.retunes} retunes, {loop.tuner.skipped} skipped "
            f"(rule {loop.tuner.rule}, every {loop.tuner.every} samples)"
            + (f"; holding the gains: {loop.tuner.last_reason}" if loop.tuner.last_reason else "")
        )
    if figures["note"]:
        lines.append(f"closed loop: {figures['note']}")
    if figures["measured"] is None:
        return "\n".join(lines)
    header = f"{'closed loop':<12} {'overshoot (%)':>14} {'settling (s)':>13} {'IAE':>12}"
    lines += ["", header, "-" * len(header)]
    for name in ("measured", "predicted"):
        m = figures[name]
        if m is None:
            continue
        settling = "-" if m["settling_time"] is None else f"{m['settling_time']:.1f}"
        lines.append(f"{name:<12} {m['overshoot']:>14.2f} {settling:>13} {m['iae']:>12.4g}")
    return "\n".join(lines)


class Progress:
    """A one-line progress bar on standard error, redrawn by a thread of its own.

    It reads the run's sample count every 0.2 s instead of subscribing to its
    events, so it costs the sampling loop nothing. Runs shorter than half a
    second never show it.
    """

    def __init__(self, experiment: Any, stream: TextIO) -> None:
        self._experiment = experiment
        self._stream = stream
        self._stop = threading.Event()
        self._shown = False
        self._thread = threading.Thread(target=self._draw_loop, name="progress", daemon=True)

    def __enter__(self) -> Progress:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        if self._shown:
            self._stream.write("\r\x1b[K")
            self._stream.flush()

    def _draw_loop(self) -> None:
        start = time.monotonic()
        if self._stop.wait(0.5):
            return
        while True:
            self._draw(time.monotonic() - start)
            if self._stop.wait(0.2):
                return

    def _draw(self, elapsed: float) -> None:
        exp = self._experiment
        done, total = exp.k, exp.samples
        fraction = done / total
        width = 30
        filled = int(fraction * width)
        bar = "#" * filled + "-" * (width - filled)
        eta = ""
        if 0 < done < total:
            eta = f"  ETA {elapsed * (total - done) / done:4.0f} s"
        line = (
            f"\r[{bar}] {100 * fraction:3.0f}%  {done}/{total} samples  t={done * exp.dt:g} s{eta}"
        )
        self._stream.write(line + "\x1b[K")
        self._stream.flush()
        self._shown = True


def _estimate_fields(estimate: Any) -> tuple[float, float, bool, str | None]:
    """(K, tau, valid, reason) of an identifier's estimate."""
    data = estimate.to_dict()
    K = data.get("K")
    tau = data.get("tau")
    valid = bool(data.get("valid", K is not None and tau is not None))
    extras = data.get("extras") or {}
    reason = data.get("reason") or (extras.get("reason") if isinstance(extras, dict) else None)
    return (
        math.nan if K is None else float(K),
        math.nan if tau is None else float(tau),
        valid,
        reason,
    )


def summary_table(result: Any, csv_path: str | None) -> str:
    """The run's line (rig, dt, samples, lateness, CSV) and each method's Ks and Ts."""
    rig = result.rig
    lines = [
        f"rig: {rig.name}   dt: {result.dt:g} s   samples: {result.samples}/"
        f"{result.samples_requested} ({result.end_reason.value})   "
        f"late: {result.late}   missed deadlines: {result.missed}"
        + (f"   csv: {csv_path}" if csv_path else ""),
    ]
    if not result.methods:
        return "\n".join(lines)
    gain_unit = f"{rig.output_unit}/{rig.input_unit}"
    header = f"{'method':<8} {'Ks (' + gain_unit + ')':>16} {'Ts (s)':>14} {'estimates':>10}  note"
    lines += ["", header, "-" * len(header)]
    for name, method in result.methods.items():
        latest = method.latest
        note = method.error or ""
        if latest is None:
            ks = ts = "-"
            note = note or "no estimate"
        else:
            K, tau, valid, reason = _estimate_fields(latest)
            ks = f"{K:.6f}" if math.isfinite(K) else "-"
            ts = f"{tau:.6f}" if math.isfinite(tau) else "-"
            if not valid and not note:
                note = reason or "no first-order meaning"
            elif method.final is None and result.ok and not note:
                note = "last of the run"
            elif len(method.k) == 0 and method.final is not None and not note:
                note = "at END"
        lines.append(f"{name:<8} {ks:>16} {ts:>14} {len(method.k):>10}  {note}".rstrip())
    return "\n".join(lines)


def json_report(result: Any, csv_path: str | None, signal_spec: str | None) -> dict[str, Any]:
    """``--json``'s object: the result's ``to_dict()`` with the signal, CSV and interruption."""
    report: dict[str, Any] = result.to_dict()
    report["signal"] = signal_spec
    report["csv"] = csv_path
    report["interrupted_by"] = (
        None if result.signum is None else signal_module.Signals(result.signum).name
    )
    return report
