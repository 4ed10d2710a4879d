"""``thermolab identify``: identify K and tau from a recorded CSV file.

The file is read by :func:`thermolab.records.read_record`: a header naming at
least the columns ``t``, ``u`` and ``y`` (seconds, volts, volts; any order,
other columns ignored, lines starting with ``#`` skipped), as
:class:`thermolab.runner.CsvRecorder` writes it or a spreadsheet exports it
(comma, semicolon or tab; decimal commas; UTF-8 or Latin-1). Every problem
with the file is reported as one line naming the line and column.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from pathlib import Path
from typing import Any

from thermolab.cli import CliError
from thermolab.records import Record, read_record

__all__ = ["METHODS", "register", "run"]

#: The methods ``--method`` accepts, with the names the table prints.
METHODS = {
    "srm": "step response",
    "lsm": "batch least squares",
    "blockls": "block least squares",
    "malsm": "moving-window least squares",
    "wlsm": "weighted least squares",
}
# The options that only some methods take (None = not given on the command line).
_APPLIES = {
    "window": ("malsm",),
    "block": ("blockls",),
    "gamma": ("wlsm",),
    "pmax": ("wlsm",),
    "p0": ("wlsm",),
    "form": ("wlsm",),
    "w0": ("wlsm",),
    "offset": ("lsm", "blockls", "malsm", "wlsm"),
    "order": ("lsm", "blockls", "malsm", "wlsm"),
    "tol": ("malsm", "wlsm"),
    "last": ("blockls", "malsm", "wlsm"),
}


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``identify`` subcommand to the ``thermolab`` parser."""
    p = subparsers.add_parser(
        "identify",
        help="identify K and tau from a CSV record (t,u,y)",
        description="Identify the first-order model (gain K, time constant tau) of a "
        "recorded experiment by one of the paper's methods. FILE is a CSV file with a "
        "header containing the columns t,u,y (seconds, volts); other columns are ignored.",
    )
    p.add_argument("file", metavar="FILE.csv", help="the record to identify")
    p.add_argument(
        "--method",
        required=True,
        choices=tuple(METHODS),
        help="srm: step response; lsm: batch least squares (eq. 12); blockls: an estimate "
        "every --block samples; malsm: moving window of --window samples; wlsm: recursive "
        "least squares with forgetting factor --gamma",
    )
    p.add_argument(
        "--dt",
        type=_positive_float("--dt"),
        help="sample period in seconds (default: the median spacing of t)",
    )
    p.add_argument("--window", type=_positive_int("--window"), help="malsm window (default 100)")
    p.add_argument("--block", type=_positive_int("--block"), help="blockls block (default 100)")
    p.add_argument("--gamma", type=_float("--gamma"), help="wlsm forgetting factor (default 0.96)")
    p.add_argument("--pmax", type=_float("--pmax"), help="wlsm initial diagonal of P (default 1e4)")
    p.add_argument(
        "--p0",
        type=_float("--p0"),
        help="wlsm, --form standard only: initial covariance P0 = P·I (default pmax)",
    )
    p.add_argument(
        "--form",
        choices=("paper", "standard"),
        help="wlsm formulation: the paper's eqs. 13-15 (default) or textbook RLS",
    )
    p.add_argument(
        "--w0",
        type=_float_list("--w0"),
        metavar="A,B",
        help="wlsm initial parameters, e.g. 0.96329,9.9082e-4 (default zeros)",
    )
    p.add_argument(
        "--offset",
        type=_offset,
        metavar="none|initial|fit|VALUE",
        help="operating point: initial (default) removes the first output sample, fit "
        "estimates a constant, none is the paper's raw form, a number is the known "
        "ambient output in volts",
    )
    p.add_argument(
        "--order",
        type=_order,
        metavar="NA,NB,DELAY",
        help="ARX order: output lags, input lags, dead time in samples beyond one "
        "(default 1,1,0: eq. 4)",
    )
    p.add_argument(
        "--tol",
        type=_positive_float("--tol"),
        help="relative band for converged_at (default 0.01: ±1 %%)",
    )
    p.add_argument(
        "--last",
        type=_positive_int("--last"),
        help="samples the statistics cover, counted from the end (default 2000)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="OUT.png", help="also save a figure (needs matplotlib)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handle ``thermolab identify``: read the file, identify, print; return the exit status.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (see :func:`register`).

    Returns
    -------
    int
        0 on success.

    Raises
    ------
    CliError
        For an option the method does not take, or a figure that cannot be
        written (the dispatcher prints it as one line).
    thermolab.errors.RecordFormatError
        For a file that cannot be read (one line naming the line and column).
    thermolab.errors.ThermoLabError
        From the method, for data or parameters it refuses.
    """
    method: str = args.method
    for option, methods in _APPLIES.items():
        if getattr(args, option) is not None and method not in methods:
            raise CliError(
                f"--{option} does not apply to --method {method} "
                f"(it applies to {', '.join(methods)})",
                status=2,
            )
    record = read_record(Path(args.file), channels=())
    dt = args.dt if args.dt is not None else record.median_dt
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = _identify(method, record, dt, args)
    summary = _summary(method, result, dt, args)
    notes = list(summary.get("warnings", []))
    for w in caught:
        text = str(w.message)
        if text not in notes:
            notes.append(text)
    summary["warnings"] = notes
    summary["file"] = str(args.file)
    summary["n_samples"] = record.n
    if args.plot:
        _save_plot(result, args.plot)
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(_table(summary))
        for note in notes:
            print(f"warning: {note}", file=sys.stderr)
    return 0


def _identify(method: str, record: Record, dt: float, args: argparse.Namespace) -> Any:
    from thermolab import ident

    common: dict[str, Any] = {}
    if args.offset is not None:
        common["offset"] = args.offset
    if args.order is not None:
        common["order"] = ident.ArxOrder(*args.order)
    if method == "srm":
        return ident.step_response(record.t, record.u, record.y)
    if method == "lsm":
        return ident.least_squares(record.u, record.y, dt, **common)
    if method == "blockls":
        block = 100 if args.block is None else args.block
        return ident.block_least_squares(record.u, record.y, dt, block, **common)
    if method == "malsm":
        window = 100 if args.window is None else args.window
        return ident.moving_window_least_squares(record.u, record.y, dt, window, **common)
    gamma = 0.96 if args.gamma is None else args.gamma
    pmax = 1e4 if args.pmax is None else args.pmax
    return ident.weighted_least_squares(
        record.u,
        record.y,
        dt,
        gamma,
        pmax,
        args.w0,
        form=args.form or "paper",
        p0=args.p0,
        **common,
    )


def _summary(method: str, result: Any, dt: float, args: argparse.Namespace) -> dict[str, Any]:
    if method in ("srm", "lsm"):
        d: dict[str, Any] = result.to_dict()
        out = {"method": method, "dt": dt, "K": d.pop("K"), "tau": d.pop("tau")}
        d.pop("method", None)
        d.pop("dt", None)
        out.update(d)
        return out
    tol = 0.01 if args.tol is None else args.tol
    last = 2000 if args.last is None else args.last
    d = result.to_dict(arrays=False, tol=tol, last=last)
    final = d.pop("final")
    out = {
        "method": method,
        "dt": dt,
        "K": final["K"],
        "tau": final["tau"],
        "valid": final["valid"],
        "reason": final["reason"],
        "stats": d.pop("stats"),
    }
    converged = d.pop("converged_at")
    if method in ("malsm", "wlsm"):
        out["converged_at"] = converged
        out["tol"] = tol
    out["last"] = last
    d.pop("method", None)
    d.pop("dt", None)
    out.update(d)
    return out


def _table(s: dict[str, Any]) -> str:
    method = s["method"]
    lines = [
        f"method  {method} ({METHODS[method]})",
        f"file    {s['file']} ({s['n_samples']} samples, dt = {s['dt']:g} s)",
    ]
    if "stats" in s:
        conv = s.get("converged_at")
        head = f"{'':10} {'final':>14} {'mean':>14} {'max':>14} {'min':>14}"
        if conv is not None:
            head += f" {'converged at':>13}"
        lines += ["", head]
        for name, label in (("K", "K"), ("tau", "tau (s)")):
            st = s["stats"][name]
            row = f"{label:10} {_num(s[name]):>14} " + " ".join(
                f"{_num(st[k]):>14}" for k in ("mean", "max", "min")
            )
            if conv is not None:
                row += f" {'-' if conv[name] is None else conv[name]:>13}"
            lines.append(row)
        lines.append(f"(statistics over the last {s['last']} samples)")
        if s.get("reason"):
            lines.append(f"final estimate not a first-order model: {s['reason']}")
        return "\n".join(lines)
    rows = [("K", _num(s["K"])), ("tau", f"{_num(s['tau'])} s")]
    if method == "srm":
        rows += [
            ("K (paper, last sample)", _num(s["K_last_sample"])),
            ("final value", f"{_num(s['final_value'])} V ({s['final_value_basis']})"),
            ("tau from", s["tau_basis"]),
            (
                "step",
                f"{s['u_before']:g} -> {s['u_after']:g} V at t = {s['step_time']:g} s "
                f"({s['direction']})",
            ),
            (
                "settled",
                f"{'yes' if s['settled'] else 'no'} "
                f"({s['time_constants_recorded']:.2f} time constants recorded)",
            ),
        ]
    else:
        if s.get("reason"):
            rows.append(("not first order", s["reason"]))
        for name, w, se in zip(s["param_names"], s["W"], s["stderr"], strict=True):
            rows.append((name, f"{_num(w)} ± {_num(se)}"))
        rows.append(
            (
                "fit",
                f"{_num(s['fit_one_step'], '.2f')} % one step, "
                f"{_num(s['fit_simulation'], '.2f')} % simulation",
            )
        )
    width = max(len(label) for label, _ in rows)
    lines.append("")
    lines += [f"{label:<{width}}  {value}" for label, value in rows]
    return "\n".join(lines)


def _num(x: Any, fmt: str = ".6f") -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and (abs(x) >= 1e6 or (x != 0.0 and abs(x) < 1e-4)):
        return f"{x:.6e}"
    return f"{x:{fmt}}"


def _save_plot(result: Any, path: str) -> None:
    try:
        fig = result.plot()
    except ImportError as exc:
        raise CliError(f"--plot: {exc}") from None
    try:
        fig.savefig(path)
    except (OSError, ValueError) as exc:
        raise CliError(f"--plot: cannot write {path}: {exc}") from None


def _float(option: str) -> Any:
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} must be a number, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{option} must be finite, got {text!r}")
        return v

    return parse


def _positive_float(option: str) -> Any:
    as_float = _float(option)

    def parse(text: str) -> float:
        v: float = as_float(text)
        if v <= 0:
            raise argparse.ArgumentTypeError(f"{option} must be > 0, got {text!r}")
        return v

    return parse


def _positive_int(option: str) -> Any:
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{option} must be a whole number, got {text!r}"
            ) from None
        if v < 1:
            raise argparse.ArgumentTypeError(f"{option} must be >= 1, got {text!r}")
        return v

    return parse


def _float_list(option: str) -> Any:
    as_float = _float(option)

    def parse(text: str) -> list[float]:
        return [as_float(part.strip()) for part in text.split(",")]

    return parse


def _offset(text: str) -> str | float:
    if text in ("none", "initial", "fit"):
        return text
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--offset must be none, initial, fit or a number of volts, got {text!r}"
        ) from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"--offset must be finite, got {text!r}")
    return v


def _order(text: str) -> tuple[int, int, int]:
    parts = [p.strip() for p in text.split(",")]
    try:
        na, nb, delay = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--order must be three whole numbers NA,NB,DELAY (e.g. 1,1,0), got {text!r}"
        ) from None
    return na, nb, delay
