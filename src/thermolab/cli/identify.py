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
from pathlib import Path
from typing import Any

from thermolab.cli import CliError
from thermolab.cli._settings import add_setting_options, given_settings, option, settings_of
from thermolab.ident.advice import advice
from thermolab.ident.registry import METHOD_NAMES, get_method, owners
from thermolab.ident.units import in_units

__all__ = ["register", "run"]


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
        choices=METHOD_NAMES,
        help="; ".join(f"{name}: {_label(name)}" for name in METHOD_NAMES),
    )
    p.add_argument(
        "--columns",
        metavar="t=COL,u=COL,y=COL",
        help="which columns are the time, the input and the output: header names (with or "
        "without their unit, any case) or positions counted from 1, e.g. t=Time,u=Q1,y=T1, or "
        "t=1,u=2,y=3 for a file without a header (default: the columns t,u,y, else the tclab "
        "Historian's Time,Q1,T1)",
    )
    p.add_argument(
        "--units",
        metavar="u=UNIT,y=UNIT",
        help="units of the input and output, e.g. u=%%,y=°C (default: from the header, as in "
        "'T1 (°C)'; volts for the lab's own t,u,y records)",
    )
    p.add_argument(
        "--dt",
        type=_positive_float("--dt"),
        help="sample period in seconds (default: the median spacing of t)",
    )
    # One option per registered setting; each says which methods take it.
    add_setting_options(p.add_argument_group("method settings"), settings_of())
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
    for setting in settings_of():
        takers = owners(setting.name)
        if getattr(args, setting.name) is not None and method not in takers:
            raise CliError(
                f"{option(setting)} does not apply to --method {method} "
                f"(it applies to {', '.join(takers)})",
                status=2,
            )
    from thermolab.records import read_record

    record = read_record(
        Path(args.file), channels=(), columns=args.columns, units=args.units, equal_times="last"
    )
    units = record.units
    u_unit, y_unit = units["u"], units["y"]
    dt = args.dt if args.dt is not None else record.median_dt
    from thermolab.errors import ThermoLabError
    from thermolab.ident.assess import assess

    merged = []
    if record.merged_times is not None:
        count, first = record.merged_times
        merged.append(
            f"duplicated time: {count} row{'s' if count > 1 else ''} shared the time stamp of the "
            f"next (first at t = {first:g} s); the last reading at each time was kept"
        )
    try:
        assessment = assess(
            method,
            record.t,
            record.u,
            record.y,
            dt,
            given_settings(args, get_method(method).settings),
            units=(u_unit, y_unit),
            notes=merged,
        )
    except ThermoLabError as exc:
        if merged:  # the refusal may come from the rows merged: say so on the same line
            exc.args = (f"{exc}; {merged[0]}",)
        raise
    result, summary, verdict = assessment.result, assessment.summary, assessment.verdict
    notes = list(summary["warnings"])
    summary["advice"] = [in_units(advice(note), u_unit, y_unit) for note in notes]
    summary["trusted"] = verdict.trusted
    summary["verdict"] = verdict.to_dict()
    k_unit = (
        f"{y_unit}/{u_unit}" if y_unit and u_unit else y_unit or (f"1/{u_unit}" if u_unit else "")
    )
    summary["units"] = {"t": "s", "u": u_unit, "y": y_unit, "K": k_unit, "tau": "s", "theta": "s"}
    summary["file"] = str(args.file)
    summary["n_samples"] = record.n
    if args.plot:
        _save_plot(result, args.plot)
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(_table(summary))
        for note, what in zip(notes, summary["advice"], strict=True):
            print(f"warning: {note}\n  what it means, what to do: {what}", file=sys.stderr)
    return 0


def _table(s: dict[str, Any]) -> str:
    method = s["method"]
    lines = [
        f"method  {method} ({_label(method)})",
        f"file    {s['file']} ({s['n_samples']} samples, dt = {s['dt']:g} s)",
    ]
    if "stats" in s:
        lines += _trajectory_table(s)
        lines += _trust_lines(s)
        return "\n".join(lines)
    un = s.get("units", {})
    u_unit, y_unit = un.get("u", "V"), un.get("y", "V")
    rows = [("K", f"{_num(s['K'])} {un.get('K', '')}".rstrip()), ("tau", f"{_num(s['tau'])} s")]
    if s.get("theta") is not None:
        rows.append(("theta (dead time)", f"{_num(s['theta'], '.6g')} s"))
    if method == "srm":
        rows += [
            ("K (paper, last sample)", _num(s["K_last_sample"])),
            ("final value", f"{_num(s['final_value'])} {y_unit} ({s['final_value_basis']})"),
            ("tau from", s["tau_basis"]),
            (
                "step",
                f"{s['u_before']:g} -> {s['u_after']:g} {u_unit} at t = {s['step_time']:g} s "
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
    if method == "oe":
        rows.append(("fit", f"{_num(s['fit_simulation'], '.2f')} % simulation (record)"))
    elif method != "srm":
        for name, w, se in zip(s["param_names"], s["W"], s["stderr"], strict=True):
            rows.append((name, f"{_num(w)} ± {_num(se)}"))
        held = s.get("fit_holdout")
        rows.append(
            (
                "fit",
                f"{_num(s['fit_one_step'], '.2f')} % one step, "
                f"{_num(s['fit_simulation'], '.2f')} % simulation (record)"
                + ("" if held is None else f", {_num(held, '.2f')} % held out"),
            )
        )
    width = max(len(label) for label, _ in rows)
    lines.append("")
    lines += [f"{label:<{width}}  {value}" for label, value in rows]
    lines += _trust_lines(s)
    return "\n".join(lines)


def _trajectory_table(s: dict[str, Any]) -> list[str]:
    # The figures the lab's run page shows for the same record (thermolab.ident.table_figures).
    figures = s["figures"]
    tol = f"±{100 * figures['tol']:g} %"
    conv: dict[str, int | None] | None = figures["converged_at"]
    if figures["over"] == "after_convergence":
        basis = f"(statistics over the {figures['last']} samples after convergence, {tol})"
    elif s["stats_over"] == "last":
        basis = f"(statistics over the last {figures['last']} samples)"
    else:
        basis = (
            f"(no convergence within the record: the estimates never stay within {tol}; "
            f"mean, max and min of the last {figures['last']} samples show their scatter)"
        )
        conv = None
    nan = {"mean": math.nan, "max": math.nan, "min": math.nan}
    stats = {name: figures[name] or nan for name in ("K", "tau")}
    head = f"{'':10} {'final':>14} {'mean':>14} {'max':>14} {'min':>14}"
    if conv is not None:
        head += f" {'converged at':>13}"
    lines = ["", head]
    for name, label in (("K", "K"), ("tau", "tau (s)")):
        st = stats[name]
        row = f"{label:10} {_num(s[name]):>14} " + " ".join(
            f"{_num(st[k]):>14}" for k in ("mean", "max", "min")
        )
        if conv is not None:
            row += f" {'-' if conv[name] is None else conv[name]:>13}"
        lines.append(row)
    lines.append(basis)
    if s.get("theta") is not None:
        lines.append(
            f"theta (dead time)  {_num(s['theta'], '.6g')} s "
            "(the order's delay; lsm and oe search it)"
        )
    if s.get("reason"):
        lines.append(f"final estimate not a first-order model: {s['reason']}")
    return lines


def _trust_lines(s: dict[str, Any]) -> list[str]:
    """The operating point, the residual test and the verdict: what a student can trust."""
    lines = [""]
    op = s.get("operating_point")
    if op is not None:
        lines.append(
            f"operating point  offset={op['handling']} (decided from the data: record starts "
            f"{op['start']}, ambient {_num(op['ambient'], '.6g')}): {op['reason']}"
        )
    elif s.get("offset") is not None:
        lines.append(f"operating point  offset={s['offset']} (given)")
    rt = s.get("residual_test")
    if rt is not None:
        verdict = "passed" if rt["passed"] else "FAILED"
        lines.append(
            f"residual test    {verdict} (whiteness {'ok' if rt['white'] else 'failed'}, "
            f"input independence {'ok' if rt['independent'] else 'failed'}, 99 % bound "
            f"±{_num(rt['bound'], '.3g')})"
        )
    v = s["verdict"]
    if v["fit_record"] is not None:
        lines.append(
            f"free-run fit     {v['fit_record']:.1f} % on the record, {v['fit_holdout']:.1f} % "
            "on its last third (predicted)"
        )
    peer = v["agreement"]
    if peer and peer.get("K") is not None:
        lines.append(
            f"compared with    {peer['method']}: K {_num(peer['K'], '.4g')}, tau "
            f"{_num(peer['tau'], '.4g')} s, theta {_num(peer['theta'], '.3g')} s"
        )
    if s["trusted"]:
        lines.append("trusted          yes")
    else:
        lines.append("trusted          NO, because:")
        lines += [f"  - {reason}" for reason in v["reasons"]]
    return lines


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


def _positive_float(flag: str) -> Any:
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{flag} must be a number, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{flag} must be finite, got {text!r}")
        if v <= 0:
            raise argparse.ArgumentTypeError(f"{flag} must be > 0, got {text!r}")
        return v

    return parse


def _label(method: str) -> str:
    """The method's title without its abbreviation: ``"weighted least squares"``."""
    return get_method(method).title.partition(" (")[0].lower()
