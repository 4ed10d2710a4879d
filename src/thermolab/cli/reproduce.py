"""``thermolab reproduce table1``: the paper's Table I, ours beside the printed figures.

Runs every row of Table I (:mod:`thermolab.reproduction`) on the exact
simulation of the reference model and prints ours, the paper's and the
deviation; ``--json`` prints the same as one JSON object and ``--plot DIR``
writes one parameter-convergence figure per row. The variant options re-run
the table under the assumptions that explain the rows the exact simulation
does not reproduce (``docs/reproduction.md``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from thermolab.cli import CliError
from thermolab.cli._words import _, any_words

if TYPE_CHECKING:
    pass

__all__ = ["register"]

_TABLES = ("table1",)
_DAQ16 = "daq16"


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``reproduce`` subcommand to the ``thermolab`` parser."""
    p = subparsers.add_parser(
        "reproduce",
        help=_("reproduce the paper's Table I on the simulated reference model"),
        description=_(
            "Run every row of the paper's Table I (SRM, LSM(1)-(3), MALSM, "
            "WLSM(1)-(6)) on the exact simulation of the reference model (Ks = 0.140090, "
            "Ts = 250.126233 s, T = 1 s) and print ours beside the paper's printed figures, "
            "with the deviation. The variant options re-run it under the assumptions "
            "examined in docs/reproduction.md."
        ),
    )
    p.add_argument("table", choices=_TABLES, help=_("the table to reproduce"))
    p.add_argument("--json", action="store_true", help=_("print one JSON object"))
    p.add_argument(
        "--plot",
        metavar="DIR",
        help=_("write one figure per row into DIR (table1-<run>.png; needs matplotlib)"),
    )
    p.add_argument(
        "--runs",
        type=_runs,
        metavar="RUN[,RUN...]",
        help=_("only these rows, e.g. 'LSM(2),WLSM(4)' (default: all)"),
    )
    variant = p.add_argument_group(
        _("variants"), _("assumptions that explain the paper's figures (docs/reproduction.md)")
    )
    variant.add_argument(
        "--solver",
        choices=("lstsq", "explicit-inverse"),
        help=_("LSM/MALSM rows: lstsq (default, SVD) or eq. 12 verbatim, inv(DᵀD) Dᵀ Y"),
    )
    variant.add_argument(
        "--covariance",
        choices=("propagated", "frozen"),
        help=_("WLSM rows: P propagated by eq. 15 (default) or frozen at pmax·I"),
    )
    variant.add_argument(
        "--paper-arithmetic",
        action="store_true",
        help=_(
            "shorthand for --solver explicit-inverse --covariance frozen, the assumptions "
            "that reproduce the paper's LSM(2) and WLSM(4)-(6)"
        ),
    )
    variant.add_argument(
        "--precision",
        choices=("float64", "float32"),
        help=_("store the measured output in single precision (float32)"),
    )
    variant.add_argument(
        "--decimals",
        type=_int_range("--decimals", 0, 15),
        metavar="N",
        help=_("round the measured output to N decimals (0-15), as a text file would"),
    )
    variant.add_argument(
        "--quantum",
        type=_quantum,
        metavar="VOLTS|daq16",
        help=_(
            "quantise the measured output to multiples of VOLTS; daq16 = 20/65536 V, "
            "the paper's 16-bit ±10 V board"
        ),
    )
    variant.add_argument(
        "--noise",
        type=_nonnegative_float("--noise"),
        metavar="SIGMA",
        help=_("add white Gaussian noise of SIGMA volts to the measured output"),
    )
    variant.add_argument(
        "--seed", type=_int_range("--seed", 0, 2**63 - 1), help=_("seed of --noise (default 0)")
    )
    variant.add_argument(
        "--after-convergence",
        type=_int_range("--after-convergence", 1, 65536),
        metavar="N",
        help=_(
            "samples a WLSM run lasts after convergence, over which its statistics are "
            "taken (default 2000, the paper's)"
        ),
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handle ``thermolab reproduce``."""
    from thermolab.reproduction import reproduce_table1

    solver = args.solver
    covariance = args.covariance
    if args.paper_arithmetic:
        for option, value, wanted in (
            ("--solver", solver, "explicit-inverse"),
            ("--covariance", covariance, "frozen"),
        ):
            if value not in (None, wanted):
                raise CliError(
                    _(
                        "--paper-arithmetic means {option} {wanted}; it contradicts {option} "
                        "{value}"
                    ).format(option=option, wanted=wanted, value=value),
                    status=2,
                )
        solver, covariance = "explicit-inverse", "frozen"
    # Only the options given on the command line; the library's defaults hold for the rest.
    options: dict[str, Any] = {
        "runs": args.runs,
        "solver": solver,
        "covariance": covariance,
        "precision": args.precision,
        "decimals": args.decimals,
        "quantum": args.quantum,
        "noise": args.noise,
        "seed": args.seed,
        "after_convergence": args.after_convergence,
    }
    given = {name: value for name, value in options.items() if value is not None}
    result = reproduce_table1(**given)
    if args.json:
        print(json.dumps(result.to_dict(), allow_nan=False))
    else:
        print(result.format(say=any_words))
    if args.plot:
        try:
            written = result.plot(args.plot)
        except ImportError:
            raise CliError(_("--plot needs matplotlib: pip install 'thermolab[plot]'")) from None
        except OSError as exc:
            raise CliError(
                _("--plot {path}: cannot write ({reason})").format(
                    path=args.plot, reason=exc.strerror or exc
                )
            ) from None
        # Keep standard output pure JSON when --json is given.
        out = sys.stderr if args.json else sys.stdout
        if len(written) == 1:
            wrote = _("wrote {count} figure to {path}")
        else:
            wrote = _("wrote {count} figures to {path}")
        print(wrote.format(count=len(written), path=args.plot), file=out)
    return 0


def _runs(text: str) -> tuple[str, ...]:
    from thermolab.reproduction import TABLE1_ROWS

    known = {row.run.lower(): row.run for row in TABLE1_ROWS}
    names: list[str] = []
    for part in text.split(","):
        key = part.strip().lower()
        if key not in known:
            raise argparse.ArgumentTypeError(
                _("unknown run {run}: Table I has {runs}").format(
                    run=repr(part.strip()), runs=", ".join(known.values())
                )
            )
        names.append(known[key])
    return tuple(names)


def _quantum(text: str) -> float:
    if text.strip().lower() == _DAQ16:
        from thermolab.reproduction import DAQ_16BIT_QUANTUM

        return DAQ_16BIT_QUANTUM
    value = _parse_float("--quantum", text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(
            _("--quantum must be > 0 volts or daq16, got {value}").format(value=repr(text))
        )
    return value


def _parse_float(option: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            _("{option} must be a number, got {value}").format(option=option, value=repr(text))
        ) from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(
            _("{option} must be finite, got {value}").format(option=option, value=repr(text))
        )
    return value


def _nonnegative_float(option: str) -> Callable[[str], float]:
    def parse(text: str) -> float:
        value = _parse_float(option, text)
        if value < 0.0:
            raise argparse.ArgumentTypeError(
                _("{option} must be >= 0, got {value}").format(option=option, value=repr(text))
            )
        return value

    return parse


def _int_range(option: str, lo: int, hi: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                _("{option} must be an integer, got {value}").format(
                    option=option, value=repr(text)
                )
            ) from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(
                _("{option} must be between {lo} and {hi}, got {value}").format(
                    option=option, lo=lo, hi=hi, value=value
                )
            )
        return value

    return parse
