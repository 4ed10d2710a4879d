"""``thermolab run``'s options: declared for its parser, then read into what a run needs.

:func:`add_run_options` adds them (the identifiers' settings come from the
method registry); :func:`number_of_samples`, :func:`clock_for` and
:func:`control_loop` turn the parsed options into the run's length, its clock
and its closed loop, refusing a bad combination as a usage error (exit 2).
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from thermolab.cli._settings import add_setting_options, settings_of
from thermolab.cli._words import _
from thermolab.ident.registry import METHOD_NAMES, Setting

__all__ = [
    "EXAMPLE_COMMANDS",
    "add_run_options",
    "clock_for",
    "control_loop",
    "identifier_settings",
    "number_of_samples",
]

#: The commands as they are typed (never translated); :func:`~thermolab.cli._words.examples`
#: puts the heading in the user's language.
EXAMPLE_COMMANDS = (
    "thermolab run --rig sim --dt 1 --duration 2000 --signal step:0:10@10 --fast",
    "thermolab run --rig sim:paper-practical --dt 1 --samples 3000 \\",
    "    --signal square:4:6:0.1 --method lsm,malsm,wlsm --speedup 100 --out run.csv",
    "thermolab run --rig tclab --dt 1 --duration 600 --signal step:0:50@30 --out kit.csv",
    "thermolab run --rig sim:tclab --dt 1 --duration 1200 --fast --control pid \\",
    "    --setpoint step:21:50@60 --tune simc --model 0.6,140,15.9",
    "thermolab run --rig sim --dt 1 --samples 3000 --fast --control pid --setpoint 1 \\",
    "    --kp 20 --ti 100 --adaptive --tune imc --tau-c 100 --pid-form pi --max-change 0.1",
)


def add_run_options(parser: argparse.ArgumentParser) -> None:
    """Add every option of ``thermolab run`` to its parser.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The ``run`` subcommand's parser.
    """
    parser.add_argument(
        "--rig",
        default="sim",
        metavar="SPEC",
        help=_(
            "sim (the paper's twin, noise-free), sim:PRESET (paper, paper-practical, tclab, "
            "kit: the kit's two heaters), tclab (a kit, auto-detected) or tclab:PORT "
            "(default: sim)"
        ),
    )
    parser.add_argument(
        "--dt", type=float, default=1.0, metavar="S", help=_("sample period in seconds (default 1)")
    )
    length = parser.add_mutually_exclusive_group(required=True)
    length.add_argument("--duration", type=float, metavar="S", help=_("run length in seconds"))
    length.add_argument("--samples", type=int, metavar="N", help=_("number of samples"))
    parser.add_argument(
        "--signal",
        metavar="SPEC",
        help=_(
            "input signal: const:U, step:U0:U1@T, square:LOW:HIGH:FREQ_HZ, "
            "sine:OFFSET:AMPLITUDE:FREQ_HZ, prbs:LOW:HIGH:BIT_SECONDS[:SEED] "
            "(required unless --control pid)"
        ),
    )
    parser.add_argument(
        "--method",
        default="all",
        metavar="LIST",
        help=_("comma-separated online methods from {methods} (default: all)").format(
            methods=", ".join(METHOD_NAMES)
        ),
    )
    parser.add_argument(
        "--input",
        default="u",
        metavar="NAME",
        help=_(
            "the input the signal drives and the methods identify from: u (default) or a "
            "further input of the rig, such as the kit's q2 (u then rests; open loop only)"
        ),
    )
    parser.add_argument(
        "--output",
        default="y",
        metavar="NAME",
        help=_(
            "the output the methods identify: y (default) or a further output of the rig, "
            "such as the kit's t2"
        ),
    )
    # The identifiers' settings, from the registry; each goes to the methods that take it.
    add_setting_options(parser.add_argument_group(_("method settings")), identifier_settings())
    speed = parser.add_mutually_exclusive_group()
    speed.add_argument(
        "--speedup",
        type=float,
        metavar="X",
        help=_("simulated rigs: run X times faster than real time (default 1: real time)"),
    )
    speed.add_argument(
        "--fast", action="store_true", help=_("simulated rigs: run as fast as possible")
    )
    parser.add_argument("--seed", type=int, metavar="N", help=_("seed of a simulated rig's noise"))
    parser.add_argument("--out", metavar="FILE.csv", help=_("write every sample to this CSV file"))
    parser.add_argument(
        "--json", action="store_true", help=_("print the result as JSON instead of a table")
    )
    parser.add_argument(
        "--max-output",
        type=float,
        metavar="Y",
        help=_(
            "stop the run if the output exceeds Y (output unit; the rig's own limit always applies)"
        ),
    )
    parser.add_argument(
        "--watchdog",
        type=float,
        default=10.0,
        metavar="S",
        help=_(
            "make the rig safe if the sampling loop stalls for S wall-clock seconds (default 10)"
        ),
    )
    _add_control_options(parser.add_argument_group(_("closed-loop control")))


def _add_control_options(group: Any) -> None:
    from thermolab.control import RULES

    group.add_argument(
        "--control",
        choices=("manual", "pid"),
        default="manual",
        help=_("manual: the signal drives the input (default); pid: a PID holds --setpoint"),
    )
    group.add_argument(
        "--setpoint",
        metavar="SPEC",
        help=_(
            "the PID's set point in the rig's output unit: a number, or a profile in the "
            "signal grammar (step:R0:R1@T ...)"
        ),
    )
    group.add_argument("--kp", type=float, metavar="KP", help=_("proportional gain"))
    group.add_argument("--ti", type=float, metavar="S", help=_("integral time in seconds"))
    group.add_argument(
        "--td", type=float, metavar="S", help=_("derivative time in seconds (default 0)")
    )
    group.add_argument(
        "--tune",
        choices=tuple(RULES),
        metavar="RULE",
        help=_(
            "tune from --model by a rule: {rules} (instead of --kp/--ti/--td; "
            "the rule --adaptive uses, default simc)"
        ).format(rules=", ".join(RULES)),
    )
    group.add_argument(
        "--model", metavar="K,TAU[,THETA]", help=_("the FOPDT model to tune from (gain, s, s)")
    )
    group.add_argument(
        "--tau-c", type=float, metavar="S", help=_("closed-loop time constant (imc, simc)")
    )
    group.add_argument(
        "--pid-form",
        choices=("pi", "pid"),
        help=_("the rule's controller form (default: the rule's)"),
    )
    group.add_argument(
        "--adaptive",
        action="store_true",
        help=_("retune the PID live from WLSM estimates (off by default)"),
    )
    group.add_argument(
        "--retune-every", type=int, default=50, metavar="N", help=_("retune every N samples")
    )
    group.add_argument(
        "--max-change",
        type=float,
        default=0.2,
        metavar="F",
        help=_("largest relative gain change per retune (default 0.2)"),
    )
    group.add_argument("--kp-range", metavar="LOW,HIGH", help=_("bounds of |Kp| when adaptive"))
    group.add_argument("--ti-range", metavar="LOW,HIGH", help=_("bounds of Ti (s) when adaptive"))
    # The loop's own pair, not --input/--output: those name the pair a run identifies,
    # and a closed-loop run identifies u -> y (heater 1 a disturbance when the PID drives q2).
    group.add_argument(
        "--heater",
        metavar="NAME",
        help=_("the heater the PID drives: u (default) or one the rig pairs, such as the kit's q2"),
    )
    group.add_argument(
        "--sensor",
        metavar="NAME",
        help=_("the sensor the PID reads: y (default) or the heater's pair, such as the kit's t2"),
    )


_PID_OPTIONS = (
    "setpoint", "kp", "ti", "td", "tune", "model", "tau_c", "pid_form", "kp_range", "ti_range",
    "heater", "sensor",
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
        if len(counts) == 1:
            said = _("{option} takes {count} comma-separated numbers, got {text}").format(
                option=option, count=counts[0], text=repr(text)
            )
        else:
            said = _("{option} takes {low} or {high} comma-separated numbers, got {text}").format(
                option=option,
                low=", ".join(str(c) for c in counts[:-1]),
                high=counts[-1],
                text=repr(text),
            )
        raise CliError(said, status=2)
    return values


def control_loop(args: argparse.Namespace) -> tuple[Any, Any, Any]:
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
            raise CliError(_("{options} need --control pid").format(options=names), status=2)
        if args.signal is None:
            raise CliError(_("--signal is required (or give --control pid)"), status=2)
        return None, None, None
    if args.setpoint is None:
        raise CliError(_("--control pid needs --setpoint (a number or a profile)"), status=2)
    if (args.heater is None) != (args.sensor is None):
        raise CliError(_("--heater and --sensor go together (a kit's q2 with t2)"), status=2)
    model = None
    if args.model is not None:
        model = FOPDT(*_numbers("--model", args.model, (2, 3)))
    tuning = None
    if args.kp is not None:
        if args.ti is None:
            raise CliError(_("--kp needs --ti (integral time in seconds)"), status=2)
        if args.tune is not None and not args.adaptive:
            raise CliError(_("give either --kp/--ti/--td or --tune, not both"), status=2)
        gains = PIDGains(args.kp, args.ti, 0.0 if args.td is None else args.td)
    elif args.ti is not None or args.td is not None:
        raise CliError(_("--ti and --td need --kp"), status=2)
    elif args.tune is None or model is None:
        raise CliError(
            _("--control pid needs gains: --kp/--ti[/--td], or --tune RULE --model K,TAU,THETA"),
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
        raise CliError(_("--kp-range and --ti-range need --adaptive"), status=2)
    try:
        setpoint: Any = float(args.setpoint)
    except ValueError:
        setpoint = parse_signal(args.setpoint, limits=_PROFILE_LIMITS)
    pair = {} if args.heater is None else {"heater": args.heater, "sensor": args.sensor}
    return ControlLoop(gains, setpoint, tuner=tuner, **pair), tuning, model


def identifier_settings() -> tuple[Setting, ...]:
    """The settings an online identifier takes (not the statistics-only ones)."""
    return tuple(s for s in settings_of() if s.role == "identify")


def number_of_samples(args: argparse.Namespace) -> int:
    """The run's length in samples, from ``--samples`` or ``--duration`` and ``--dt``."""
    from thermolab.cli import CliError

    if not (math.isfinite(args.dt) and args.dt > 0):
        raise CliError(
            _("--dt must be a positive number of seconds, got {dt}").format(dt=f"{args.dt:g}"),
            status=2,
        )
    if args.samples is not None:
        if args.samples < 1:
            raise CliError(
                _("--samples must be at least 1, got {samples}").format(samples=args.samples),
                status=2,
            )
        return int(args.samples)
    duration = args.duration
    if not (math.isfinite(duration) and duration > 0):
        raise CliError(
            _("--duration must be a positive number of seconds, got {duration}").format(
                duration=f"{duration:g}"
            ),
            2,
        )
    # A duration of 2000 s at 1 s is 2000 samples (t = 0 ... 1999 s); the tolerance
    # keeps 0.3 / 0.1 from becoming 2 samples.
    n = math.floor(duration / args.dt + 1e-9)
    if n < 1:
        raise CliError(
            _("--duration {duration} s is shorter than one period (--dt {dt})").format(
                duration=f"{duration:g}", dt=f"{args.dt:g}"
            )
        )
    return int(n)


def clock_for(args: argparse.Namespace, simulated: bool) -> Any:
    """The run's clock: real time for hardware; ``--fast`` or ``--speedup`` for a simulated rig."""
    from thermolab.cli import CliError
    from thermolab.rigs import RealClock, VirtualClock, make_clock

    if not simulated:
        if args.fast or (args.speedup is not None and args.speedup != 1.0):
            raise CliError(
                _("a real rig ({rig}) runs in real time: drop --fast / --speedup").format(
                    rig=args.rig
                ),
                status=2,
            )
        return RealClock()
    if args.fast:
        return VirtualClock()
    if args.speedup is not None:
        if not (args.speedup > 0 and not math.isnan(args.speedup)):
            raise CliError(
                _("--speedup must be a positive number, got {speedup}").format(
                    speedup=f"{args.speedup:g}"
                ),
                2,
            )
        return make_clock(args.speedup)
    return RealClock()
