"""``thermolab run``: drive a rig, record it, and identify its model live.

Opens a rig (the digital twin or a TCLab kit), applies an excitation signal for
a number of samples, writes every sample to a CSV file as it is taken (columns
``t,u,y`` first, so the file feeds straight into ``thermolab identify``), runs
the chosen online identifiers at every sample and prints each method's Ks and
Ts at the end (a table, or JSON with ``--json``).

With ``--control pid`` the run is closed-loop: a PID holds the output at
``--setpoint`` (a number or a profile such as ``step:21:50@60``, in the rig's
output unit), with gains given (``--kp/--ti/--td``) or tuned from an FOPDT
model (``--tune simc --model K,TAU,THETA [--tau-c S]``), optionally retuned
live from WLSM (``--adaptive``). The set point, the PID's output, the error and
the mode are columns of the CSV; the summary adds the closed-loop figures
(overshoot, 2 % settling time, IAE) measured and, with ``--model``, predicted.

Exit status: 0 when the run completes; 1 when it stops on a device fault or an
interlock (one line on standard error; the samples already taken stay in the
CSV and the heater is off); 130 on SIGINT and 143 on SIGTERM (same safe end).
"""

from __future__ import annotations

import argparse
import json
import math
import signal as signal_module
import sys
import threading
import time
from typing import Any, TextIO

from thermolab.cli._settings import add_setting_options, given_settings, settings_of
from thermolab.ident.registry import METHOD_NAMES, Setting

__all__ = ["register"]

_EXAMPLES = """\
examples:
  thermolab run --rig sim --dt 1 --duration 2000 --signal step:0:10@10 --fast
  thermolab run --rig sim:paper-practical --dt 1 --samples 3000 \\
      --signal square:4:6:0.1 --method lsm,malsm,wlsm --speedup 100 --out run.csv
  thermolab run --rig tclab --dt 1 --duration 600 --signal step:0:50@30 --out kit.csv
  thermolab run --rig sim:tclab --dt 1 --duration 1200 --fast --control pid \
      --setpoint step:21:50@60 --tune simc --model 0.6,140,15.9
  thermolab run --rig sim --dt 1 --samples 3000 --fast --control pid --setpoint 1 \
      --kp 20 --ti 100 --adaptive --tune imc --tau-c 100 --pid-form pi --max-change 0.1
"""


def register(subparsers: Any) -> None:
    """Add the ``run`` subcommand to the ``thermolab`` parser.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The subparsers of the main parser.
    """
    parser = subparsers.add_parser(
        "run",
        help="run an experiment on a rig and identify its model live",
        description="Run an experiment on a rig (the digital twin or a TCLab kit): apply a "
        "signal, record every sample, identify Ks and Ts with online methods.",
        epilog=_EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--rig",
        default="sim",
        metavar="SPEC",
        help="sim (the paper's twin, noise-free), sim:PRESET (paper, paper-practical, tclab), "
        "tclab (a kit, auto-detected) or tclab:PORT (default: sim)",
    )
    parser.add_argument(
        "--dt", type=float, default=1.0, metavar="S", help="sample period in seconds (default 1)"
    )
    length = parser.add_mutually_exclusive_group(required=True)
    length.add_argument("--duration", type=float, metavar="S", help="run length in seconds")
    length.add_argument("--samples", type=int, metavar="N", help="number of samples")
    parser.add_argument(
        "--signal",
        metavar="SPEC",
        help="input signal: const:U, step:U0:U1@T, square:LOW:HIGH:FREQ_HZ, "
        "sine:OFFSET:AMPLITUDE:FREQ_HZ, prbs:LOW:HIGH:BIT_SECONDS[:SEED] "
        "(required unless --control pid)",
    )
    parser.add_argument(
        "--method",
        default="all",
        metavar="LIST",
        help=f"comma-separated online methods from {', '.join(METHOD_NAMES)} (default: all)",
    )
    # The identifiers' settings, from the registry; each goes to the methods that take it.
    add_setting_options(parser.add_argument_group("method settings"), _identifier_settings())
    speed = parser.add_mutually_exclusive_group()
    speed.add_argument(
        "--speedup",
        type=float,
        metavar="X",
        help="simulated rigs: run X times faster than real time (default 1: real time)",
    )
    speed.add_argument(
        "--fast", action="store_true", help="simulated rigs: run as fast as possible"
    )
    parser.add_argument("--seed", type=int, metavar="N", help="seed of a simulated rig's noise")
    parser.add_argument("--out", metavar="FILE.csv", help="write every sample to this CSV file")
    parser.add_argument(
        "--json", action="store_true", help="print the result as JSON instead of a table"
    )
    parser.add_argument(
        "--max-output",
        type=float,
        metavar="Y",
        help="stop the run if the output exceeds Y (output unit; the rig's own limit "
        "always applies)",
    )
    parser.add_argument(
        "--watchdog",
        type=float,
        default=10.0,
        metavar="S",
        help="make the rig safe if the sampling loop stalls for S wall-clock seconds (default 10)",
    )
    _add_control_options(parser.add_argument_group("closed-loop control"))
    parser.set_defaults(handler=_run)


def _add_control_options(group: Any) -> None:
    from thermolab.control import RULES

    group.add_argument(
        "--control",
        choices=("manual", "pid"),
        default="manual",
        help="manual: the signal drives the input (default); pid: a PID holds --setpoint",
    )
    group.add_argument(
        "--setpoint",
        metavar="SPEC",
        help="the PID's set point in the rig's output unit: a number, or a profile in the "
        "signal grammar (step:R0:R1@T ...)",
    )
    group.add_argument("--kp", type=float, metavar="KP", help="proportional gain")
    group.add_argument("--ti", type=float, metavar="S", help="integral time in seconds")
    group.add_argument(
        "--td", type=float, metavar="S", help="derivative time in seconds (default 0)"
    )
    group.add_argument(
        "--tune",
        choices=tuple(RULES),
        metavar="RULE",
        help=f"tune from --model by a rule: {', '.join(RULES)} (instead of --kp/--ti/--td; "
        "the rule --adaptive uses, default simc)",
    )
    group.add_argument(
        "--model", metavar="K,TAU[,THETA]", help="the FOPDT model to tune from (gain, s, s)"
    )
    group.add_argument(
        "--tau-c", type=float, metavar="S", help="closed-loop time constant (imc, simc)"
    )
    group.add_argument(
        "--pid-form", choices=("pi", "pid"), help="the rule's controller form (default: the rule's)"
    )
    group.add_argument(
        "--adaptive",
        action="store_true",
        help="retune the PID live from WLSM estimates (off by default)",
    )
    group.add_argument(
        "--retune-every", type=int, default=50, metavar="N", help="retune every N samples"
    )
    group.add_argument(
        "--max-change",
        type=float,
        default=0.2,
        metavar="F",
        help="largest relative gain change per retune (default 0.2)",
    )
    group.add_argument("--kp-range", metavar="LOW,HIGH", help="bounds of |Kp| when adaptive")
    group.add_argument("--ti-range", metavar="LOW,HIGH", help="bounds of Ti (s) when adaptive")


_PID_OPTIONS = (
    "setpoint", "kp", "ti", "td", "tune", "model", "tau_c", "pid_form", "kp_range", "ti_range",
)  # fmt: skip
# A set-point profile's own range check is the control loop's (the rig's output range).
_PROFILE_LIMITS = (-1e9, 1e9)


def _numbers(option: str, text: str, counts: tuple[int, ...]) -> tuple[float, ...]:
    from thermolab.cli import CliError

    try:
        values = tuple(float(part) for part in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in counts or not all(math.isfinite(v) for v in values):
        shape = " or ".join(str(c) for c in counts)
        raise CliError(f"{option} takes {shape} comma-separated numbers, got {text!r}", status=2)
    return values


def _control_loop(args: argparse.Namespace) -> tuple[Any, Any, Any]:
    """(ControlLoop or None, Tuning or None, FOPDT or None) from the options."""
    from thermolab.cli import CliError
    from thermolab.control import FOPDT, GainBounds, PIDGains, tune
    from thermolab.runner import ControlLoop
    from thermolab.signals import parse_signal

    if args.control != "pid":
        given = [o for o in _PID_OPTIONS if getattr(args, o) is not None]
        if args.adaptive:
            given.append("adaptive")
        if given:
            names = ", ".join("--" + o.replace("_", "-") for o in given)
            raise CliError(f"{names} need --control pid", status=2)
        if args.signal is None:
            raise CliError("--signal is required (or give --control pid)", status=2)
        return None, None, None
    if args.setpoint is None:
        raise CliError("--control pid needs --setpoint (a number or a profile)", status=2)
    model = None
    if args.model is not None:
        model = FOPDT(*_numbers("--model", args.model, (2, 3)))
    tuning = None
    if args.kp is not None:
        if args.ti is None:
            raise CliError("--kp needs --ti (integral time in seconds)", status=2)
        if args.tune is not None and not args.adaptive:
            raise CliError("give either --kp/--ti/--td or --tune, not both", status=2)
        gains = PIDGains(args.kp, args.ti, 0.0 if args.td is None else args.td)
    elif args.ti is not None or args.td is not None:
        raise CliError("--ti and --td need --kp", status=2)
    elif args.tune is None or model is None:
        raise CliError(
            "--control pid needs gains: --kp/--ti[/--td], or --tune RULE --model K,TAU,THETA",
            status=2,
        )
    else:
        tuning = tune(model, args.tune, form=args.pid_form, tau_c=args.tau_c)
        gains = tuning.gains
    tuner = None
    if args.adaptive:
        from thermolab.runner import adaptive_tuner

        ranges: dict[str, tuple[float, float]] = {}
        for option, key in (("--kp-range", "kp_range"), ("--ti-range", "ti_range")):
            text = getattr(args, key)
            if text is not None:
                low, high = _numbers(option, text, (2,))
                ranges[key[:2]] = (low, high)
        tuner = adaptive_tuner(
            args.dt,
            gains,
            rule=args.tune,
            every=args.retune_every,
            form=args.pid_form,
            tau_c=args.tau_c,
            theta=0.0 if model is None else model.theta,
            max_change=args.max_change,
            bounds=GainBounds(**ranges),
        )
    elif args.kp_range is not None or args.ti_range is not None:
        raise CliError("--kp-range and --ti-range need --adaptive", status=2)
    try:
        setpoint: Any = float(args.setpoint)
    except ValueError:
        setpoint = parse_signal(args.setpoint, limits=_PROFILE_LIMITS)
    return ControlLoop(gains, setpoint, tuner=tuner), tuning, model


def _closed_loop_figures(result: Any, loop: Any, model: Any) -> dict[str, Any]:
    """Measured (and, with a model, predicted) overshoot, settling time and IAE."""
    from thermolab.control import predict_record_step, rest_warning, step_metrics
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
    figures["note"] = rest_warning(model, measured, result.t, result.y)
    return figures


def _control_table(result: Any, loop: Any, tuning: Any, figures: dict[str, Any]) -> str:
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


def _identifier_settings() -> tuple[Setting, ...]:
    """The settings an online identifier takes (not the statistics-only ones)."""
    return tuple(s for s in settings_of() if s.role == "identify")


def _number_of_samples(args: argparse.Namespace) -> int:
    from thermolab.cli import CliError

    if not (math.isfinite(args.dt) and args.dt > 0):
        raise CliError(f"--dt must be a positive number of seconds, got {args.dt:g}", status=2)
    if args.samples is not None:
        if args.samples < 1:
            raise CliError(f"--samples must be at least 1, got {args.samples}", status=2)
        return int(args.samples)
    duration = args.duration
    if not (math.isfinite(duration) and duration > 0):
        raise CliError(f"--duration must be a positive number of seconds, got {duration:g}", 2)
    # A duration of 2000 s at 1 s is 2000 samples (t = 0 ... 1999 s); the tolerance
    # keeps 0.3 / 0.1 from becoming 2 samples.
    n = math.floor(duration / args.dt + 1e-9)
    if n < 1:
        raise CliError(f"--duration {duration:g} s is shorter than one period (--dt {args.dt:g})")
    return int(n)


def _clock_for(args: argparse.Namespace, simulated: bool) -> Any:
    from thermolab.cli import CliError
    from thermolab.rigs import RealClock, VirtualClock, make_clock

    if not simulated:
        if args.fast or (args.speedup is not None and args.speedup != 1.0):
            raise CliError(
                f"a real rig ({args.rig}) runs in real time: drop --fast / --speedup", status=2
            )
        return RealClock()
    if args.fast:
        return VirtualClock()
    if args.speedup is not None:
        if not (args.speedup > 0 and not math.isnan(args.speedup)):
            raise CliError(f"--speedup must be a positive number, got {args.speedup:g}", 2)
        return make_clock(args.speedup)
    return RealClock()


class _Progress:
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

    def __enter__(self) -> _Progress:
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


def _summary_table(result: Any, csv_path: str | None) -> str:
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


def _json_report(result: Any, csv_path: str | None, signal_spec: str | None) -> dict[str, Any]:
    report: dict[str, Any] = result.to_dict()
    report["signal"] = signal_spec
    report["csv"] = csv_path
    report["interrupted_by"] = (
        None if result.signum is None else signal_module.Signals(result.signum).name
    )
    return report


def _run(args: argparse.Namespace) -> int:
    from thermolab.cli import CliError
    from thermolab.jsonsafe import json_safe
    from thermolab.records import RUN_CHANNELS
    from thermolab.rigs import open_rig
    from thermolab.runner import (
        CsvRecorder,
        Experiment,
        Interlocks,
        RunResult,
        closed_loop_channels,
        interrupt_signal,
        termination_signals,
    )
    from thermolab.runner.methods import build_identifiers, parse_methods
    from thermolab.signals import parse_signal

    n = _number_of_samples(args)
    methods = parse_methods(args.method)
    loop, tuning, model = _control_loop(args)
    # Only hardware is bound to real time; an unknown rig is reported by open_rig.
    simulated = args.rig.strip().partition(":")[0] != "tclab"
    clock = _clock_for(args, simulated)
    interlocks = Interlocks(output_max=args.max_output, watchdog=args.watchdog)
    result: RunResult | None = None
    # The rig first, then the handlers: while the run goes on, SIGTERM and SIGINT
    # unwind it through its safe end (heater off, CSV closed); afterwards the
    # handlers the rig's driver installed are back as they were.
    with open_rig(args.rig, clock=clock, seed=args.seed) as rig, termination_signals():
        info = rig.describe()
        signal = None if args.signal is None else parse_signal(args.signal, limits=info.input_range)
        identifiers = build_identifiers(
            methods, args.dt, **given_settings(args, _identifier_settings())
        )
        channels = RUN_CHANNELS
        if loop is not None:
            loop.bind(info, interlocks)
            channels = (*RUN_CHANNELS, *closed_loop_channels(rig, loop))
        recorder = (
            CsvRecorder(args.out, fsync=not simulated, channels=channels) if args.out else None
        )
        experiment = Experiment(
            rig,
            args.dt,
            n,
            signal=signal,
            identifiers=identifiers,
            recorder=recorder,
            interlocks=interlocks,
            controller=loop,
        )
        progress = _Progress(experiment, sys.stderr) if sys.stderr.isatty() else None
        try:
            if progress is not None:
                with progress:
                    result = experiment.run()
            else:
                result = experiment.run()
        except BaseException as exc:
            signum = interrupt_signal(exc)
            if signum is None:
                raise
            taken = experiment.k
            kept = f"; {taken} samples kept in {args.out}" if args.out else ""
            name = signal_module.Signals(signum).name
            print(f"interrupted by {name}: {info.name} made safe{kept}", file=sys.stderr)
            return 128 + signum
    assert result is not None
    figures = None if loop is None else _closed_loop_figures(result, loop, model)
    if args.json:
        report = _json_report(result, args.out, None if signal is None else signal.spec)
        if loop is not None:
            report["control"] = {
                **report.get("control", {}),
                "tuning": None if tuning is None else tuning.to_dict(),
                "model": None if model is None else model.to_dict(),
                "closed_loop": figures,
            }
        print(json.dumps(json_safe(report), indent=2))
    else:
        print(_summary_table(result, args.out))
        if loop is not None:
            assert figures is not None
            print()
            print(_control_table(result, loop, tuning, figures))
    if not result.ok:
        kept = f"; {result.samples} samples kept in {args.out}" if args.out else ""
        raise CliError(
            f"run stopped at sample {result.samples} (t={result.samples * result.dt:g} s): "
            f"{result.message}; {info.name} made safe{kept}"
        )
    return 0
