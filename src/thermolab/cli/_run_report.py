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

from thermolab.cli._words import _, decimal, library_text

__all__ = [
    "Progress",
    "closed_loop_figures",
    "control_table",
    "json_report",
    "summary_table",
]


def closed_loop_figures(
    result: Any, loop: Any, model: Any
) -> tuple[dict[str, Any], tuple[str, ...]]:
    """Measured (and, with a model, predicted) overshoot, settling time and IAE.

    Returns the figures (``--json``'s ``closed_loop``, whose ``note`` is the notes
    joined in English) and the notes one by one, for :func:`control_table` to say
    each in the user's language.
    """
    from thermolab.control import (
        predict_record_step,
        rest_warning,
        settling_warning,
        step_metrics,
    )
    from thermolab.errors import InvalidDataError

    figures: dict[str, Any] = {"measured": None, "predicted": None, "note": None}
    r = result.extra["r"]
    rig = result.rig
    # The loop's pair: the run's u and y, or a further pair's columns (a kit's q2, t2).
    y = result.y if loop.sensor == "y" else result.extra[loop.sensor]
    u = result.u if loop.heater == "u" else result.extra[loop.heater]
    rest, limits = rig.safe_input, (rig.input_min, rig.input_max)
    if loop.heater != "u":
        heater = rig.inputs[loop.heater]
        rest, limits = heater.default, (heater.minimum, heater.maximum)
    try:
        if model is None:
            figures["measured"] = step_metrics(result.t, r, y).to_dict()
            return figures, ()
        # The lab's figures come from the same function: one operating point rule.
        measured, predicted = predict_record_step(
            model,
            loop.initial_gains,
            result.t,
            r,
            y,
            u,
            dt=result.dt,
            u_rest=rest,
            u_limits=limits,
            derivative_filter=loop.derivative_filter,
        )
    except InvalidDataError as exc:
        figures["note"] = str(exc)
        return figures, (str(exc),)
    figures["measured"] = measured.to_dict()
    figures["predicted"] = predicted.metrics.to_dict()
    notes = tuple(
        n
        for n in (
            rest_warning(model, measured, result.t, y),
            settling_warning(measured, predicted.metrics),
        )
        if n
    )
    figures["note"] = "; ".join(notes) or None
    return figures, notes


def control_table(
    result: Any,
    loop: Any,
    tuning: Any,
    figures: dict[str, Any],
    notes: tuple[str, ...],
) -> str:
    """The control line (mode, set point, gains, tuning) and the closed-loop figures' table.

    ``notes`` are the library's notes on the figures one by one (from
    :func:`closed_loop_figures`), each said in the user's language.
    """
    rig = result.rig
    g = loop.gains
    how = f"  ({tuning.rule} {tuning.form}" if tuning is not None else ""
    if tuning is not None and tuning.tau_c is not None:
        how += f", tau_c {tuning.tau_c:g} s"
    how += ")" if tuning is not None else ""
    if loop.auto:
        control = _(
            "control: PID auto   set point {setpoint} {unit}   Kp {kp}  Ti {ti} s  Td {td} s"
            "{tuning}"
        )
    else:
        control = _(
            "control: PID manual   set point {setpoint} {unit}   Kp {kp}  Ti {ti} s  Td {td} s"
            "{tuning}"
        )
    lines = [
        decimal(
            control.format(
                setpoint=f"{loop.setpoint:g}",
                unit=rig.output_unit,
                kp=f"{g.Kp:.6g}",
                ti=f"{g.Ti:.6g}",
                td=f"{g.Td:.6g}",
                tuning=how,
            )
        )
    ]
    tuner = loop.tuner
    if tuner is not None:
        counts = {
            "retunes": tuner.retunes,
            "skipped": tuner.skipped,
            "rule": tuner.rule,
            "every": tuner.every,
        }
        if tuner.last_reason:
            lines.append(
                _(
                    "adaptive: {retunes} retunes, {skipped} skipped (rule {rule}, every {every} "
                    "samples); holding the gains: {reason}"
                ).format(**counts, reason=library_text(tuner.last_reason))
            )
        else:
            lines.append(
                _(
                    "adaptive: {retunes} retunes, {skipped} skipped (rule {rule}, every {every} "
                    "samples)"
                ).format(**counts)
            )
    if notes:
        said = "; ".join(library_text(n) for n in notes)
        lines.append(_("closed loop: {note}").format(note=said))
    if figures["measured"] is None:
        return "\n".join(lines)
    # The widths are the English table's, widened to fit the words in the user's language.
    rows = {"measured": _("measured"), "predicted": _("predicted")}
    title, overshoot, settling_title = _("closed loop"), _("overshoot (%)"), _("settling (s)")
    w0 = max(12, len(title), *(len(label) for label in rows.values()))
    w1 = max(14, len(overshoot))
    w2 = max(13, len(settling_title))
    header = f"{title:<{w0}} {overshoot:>{w1}} {settling_title:>{w2}} {'IAE':>12}"
    lines += ["", header, "-" * len(header)]
    for name, label in rows.items():
        m = figures[name]
        if m is None:
            continue
        settling = "-" if m["settling_time"] is None else f"{m['settling_time']:.1f}"
        row = f"{label:<{w0}} {m['overshoot']:>{w1}.2f} {settling:>{w2}} {m['iae']:>12.4g}"
        lines.append(decimal(row))
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
        counted = _("{done}/{total} samples  t={t} s").format(
            done=done, total=total, t=f"{done * exp.dt:g}"
        )
        eta = ""
        if 0 < done < total:
            eta = "  " + _("ETA {seconds} s").format(
                seconds=f"{elapsed * (total - done) / done:4.0f}"
            )
        line = f"\r[{bar}] {100 * fraction:3.0f}%  {counted}{eta}"
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
    words = {
        "rig": rig.name,
        "dt": decimal(f"{result.dt:g}"),
        "samples": result.samples,
        "requested": result.samples_requested,
        "end": _end_reason(result.end_reason.value),
        "late": result.late,
        "missed": result.missed,
    }
    if csv_path:
        run_line = _(
            "rig: {rig}   dt: {dt} s   samples: {samples}/{requested} ({end})   "
            "late: {late}   missed deadlines: {missed}   csv: {path}"
        ).format(**words, path=csv_path)
    else:
        run_line = _(
            "rig: {rig}   dt: {dt} s   samples: {samples}/{requested} ({end})   "
            "late: {late}   missed deadlines: {missed}"
        ).format(**words)
    lines = [run_line]
    if not result.methods:
        return "\n".join(lines)
    gain_unit = f"{rig.output_unit}/{rig.input_unit}"
    # The widths are the English table's, widened to fit the words in the user's language.
    method_title, estimates_title, note_title = _("method"), _("estimates"), _("note")
    w0 = max(8, len(method_title))
    w3 = max(10, len(estimates_title))
    header = (
        f"{method_title:<{w0}} {'Ks (' + gain_unit + ')':>16} {'Ts (s)':>14} "
        f"{estimates_title:>{w3}}  {note_title}"
    )
    lines += ["", header, "-" * len(header)]
    for name, method in result.methods.items():
        latest = method.latest
        note = library_text(method.error) if method.error else ""
        if latest is None:
            ks = ts = "-"
            note = note or _("no estimate")
        else:
            K, tau, valid, reason = _estimate_fields(latest)
            ks = decimal(f"{K:.6f}") if math.isfinite(K) else "-"
            ts = decimal(f"{tau:.6f}") if math.isfinite(tau) else "-"
            if not valid and not note:
                note = library_text(reason) if reason else _("no first-order meaning")
            elif method.final is None and result.ok and not note:
                note = _("last of the run")
            elif len(method.k) == 0 and method.final is not None and not note:
                note = _("at END")
        lines.append(f"{name:<{w0}} {ks:>16} {ts:>14} {len(method.k):>{w3}}  {note}".rstrip())
    return "\n".join(lines)


def _end_reason(value: str) -> str:
    """Why the run ended (an :class:`~thermolab.runner.EndReason`'s value) in the user's words."""
    words = {
        "completed": _("completed"),
        "ended": _("ended"),
        "interlock": _("interlock"),
        "rig_fault": _("rig_fault"),
        "watchdog": _("watchdog"),
        "error": _("error"),
        "aborted": _("aborted"),
    }
    return words.get(value, value)


def json_report(result: Any, csv_path: str | None, signal_spec: str | None) -> dict[str, Any]:
    """``--json``'s object: the result's ``to_dict()`` with the signal, CSV and interruption."""
    report: dict[str, Any] = result.to_dict()
    report["signal"] = signal_spec
    report["csv"] = csv_path
    report["interrupted_by"] = (
        None if result.signum is None else signal_module.Signals(result.signum).name
    )
    return report
