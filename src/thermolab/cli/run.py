"""``thermolab run``: drive a rig, record it, and identify its model live.

Opens a rig (the digital twin or a TCLab kit), applies an excitation signal for
a number of samples, writes every sample to a CSV file as it is taken (columns
``t,u,y`` first, so the file feeds straight into ``thermolab identify``), runs
the chosen online identifiers at every sample and prints each method's Ks and
Ts at the end (a table, or JSON with ``--json``). ``--input``/``--output`` choose
the pair identified (a kit's ``q2``/``t2``; default ``u``/``y``).

With ``--control pid`` the run is closed-loop: a PID holds the output at
``--setpoint`` (a number or a profile such as ``step:21:50@60``, in the rig's
output unit), with gains given (``--kp/--ti/--td``) or tuned from an FOPDT
model (``--tune simc --model K,TAU,THETA [--tau-c S]``), optionally retuned
live from WLSM (``--adaptive``). The set point, the PID's output, the error and
the mode are columns of the CSV; the summary adds the closed-loop figures
(overshoot, 2 % settling time, IAE) measured and, with ``--model``, predicted.
``--heater``/``--sensor`` name the loop's pair (a kit's ``q2``/``t2``; default
``u``/``y``): the run's input ``u`` then rests, a disturbance.

Exit status: 0 when the run completes; 1 when it stops on a device fault or an
interlock (one line on standard error; the samples already taken stay in the
CSV and the heater is off); 130 on SIGINT and 143 on SIGTERM (same safe end).
"""

from __future__ import annotations

import argparse
import json
import signal as signal_module
import sys
from typing import Any

from thermolab.cli._run_args import (
    EXAMPLE_COMMANDS,
    add_run_options,
    clock_for,
    control_loop,
    identifier_settings,
    number_of_samples,
)
from thermolab.cli._run_report import (
    Progress,
    closed_loop_figures,
    control_table,
    json_report,
    summary_table,
)
from thermolab.cli._settings import given_settings
from thermolab.cli._words import _, examples, library_text

__all__ = ["register"]


def register(subparsers: Any) -> None:
    """Add the ``run`` subcommand to the ``thermolab`` parser.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The subparsers of the main parser.
    """
    parser = subparsers.add_parser(
        "run",
        help=_("run an experiment on a rig and identify its model live"),
        description=_(
            "Run an experiment on a rig (the digital twin or a TCLab kit): apply a "
            "signal, record every sample, identify Ks and Ts with online methods."
        ),
        epilog=examples(*EXAMPLE_COMMANDS),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_run_options(parser)
    parser.set_defaults(handler=_run)


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
        check_pair,
        extra_channels,
        interrupt_signal,
        termination_signals,
    )
    from thermolab.runner.methods import build_identifiers, parse_methods
    from thermolab.signals import parse_signal

    n = number_of_samples(args)
    methods = parse_methods(args.method)
    loop, tuning, model = control_loop(args)
    # Only hardware is bound to real time; an unknown rig is reported by open_rig.
    simulated = args.rig.strip().partition(":")[0] != "tclab"
    clock = clock_for(args, simulated)
    interlocks = Interlocks(output_max=args.max_output, watchdog=args.watchdog)
    result: RunResult | None = None
    # The rig first, then the handlers: while the run goes on, SIGTERM and SIGINT
    # unwind it through its safe end (heater off, CSV closed); afterwards the
    # handlers the rig's driver installed are back as they were.
    with open_rig(args.rig, clock=clock, seed=args.seed) as rig, termination_signals():
        info = rig.describe()
        pair = check_pair(info, args.input, args.output)  # the pair identified (u, y: default)
        limits = pair.input_range(info)
        signal = None if args.signal is None else parse_signal(args.signal, limits=limits)
        identifiers = build_identifiers(
            methods, args.dt, **given_settings(args, identifier_settings())
        )
        if loop is not None:
            loop.bind(info, interlocks)
        channels = (*RUN_CHANNELS, *extra_channels(rig, info, loop))  # a kit's t2, q2 too
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
            pair=pair,
        )
        progress = Progress(experiment, sys.stderr) if sys.stderr.isatty() else None
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
            name = signal_module.Signals(signum).name
            if args.out:
                said = _(
                    "interrupted by {signal}: {rig} made safe; {samples} samples kept in {path}"
                ).format(signal=name, rig=info.name, samples=experiment.k, path=args.out)
            else:
                said = _("interrupted by {signal}: {rig} made safe").format(
                    signal=name, rig=info.name
                )
            print(said, file=sys.stderr)
            return 128 + signum
    assert result is not None
    figures, notes = (None, ()) if loop is None else closed_loop_figures(result, loop, model)
    if args.json:
        report = json_report(result, args.out, None if signal is None else signal.spec)
        report["pair"] = pair.to_dict()
        if loop is not None:
            report["control"] = {
                **report.get("control", {}),
                "tuning": None if tuning is None else tuning.to_dict(),
                "model": None if model is None else model.to_dict(),
                "closed_loop": figures,
            }
        print(json.dumps(json_safe(report), indent=2))
    else:
        if not pair.standard:
            print(_("identified pair: {input} -> {output}").format(**pair.to_dict()))
        print(summary_table(result, args.out))
        if loop is not None:
            assert figures is not None
            print()
            if loop.drives_further:  # a kit's heater 2 from sensor 2
                print(_("closed loop: {heater} from {sensor}").format(**loop.to_dict()))
            print(control_table(result, loop, tuning, figures, notes))
    if not result.ok:
        words = {
            "sample": result.samples,
            "t": f"{result.samples * result.dt:g}",
            "reason": library_text(result.message),
            "rig": info.name,
        }
        if args.out:
            said = _(
                "run stopped at sample {sample} (t={t} s): {reason}; {rig} made safe; "
                "{samples} samples kept in {path}"
            ).format(**words, samples=result.samples, path=args.out)
        else:
            said = _("run stopped at sample {sample} (t={t} s): {reason}; {rig} made safe").format(
                **words
            )
        raise CliError(said)
    return 0
