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
from thermolab.cli._words import _, cli_language, decimal, library_text
from thermolab.ident.advice import advice
from thermolab.ident.registry import METHOD_NAMES, get_method, owners
from thermolab.ident.units import in_units

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``identify`` subcommand to the ``thermolab`` parser."""
    p = subparsers.add_parser(
        "identify",
        help=_("identify K and tau from a CSV record (t,u,y)"),
        description=_(
            "Identify the first-order model (gain K, time constant tau) of a "
            "recorded experiment by one of the paper's methods. FILE is a CSV file with a "
            "header containing the columns t,u,y (seconds, volts); other columns are ignored."
        ),
    )
    p.add_argument("file", metavar="FILE.csv", help=_("the record to identify"))
    p.add_argument(
        "--method",
        required=True,
        choices=METHOD_NAMES,
        help="; ".join(f"{name}: {_label(name)}" for name in METHOD_NAMES),
    )
    p.add_argument(
        "--columns",
        metavar="t=COL,u=COL,y=COL",
        help=_(
            "which columns are the time, the input and the output: header names (with or "
            "without their unit, any case) or positions counted from 1, e.g. t=Time,u=Q1,y=T1, "
            "or t=1,u=2,y=3 for a file without a header (default: the columns t,u,y, else the "
            "tclab Historian's Time,Q1,T1)"
        ),
    )
    p.add_argument(
        "--units",
        metavar="u=UNIT,y=UNIT",
        help=_(
            "units of the input and output, e.g. u=%%,y=°C (default: from the header, as in "
            "'T1 (°C)'; volts for the lab's own t,u,y records)"
        ),
    )
    p.add_argument(
        "--dt",
        type=_positive_float("--dt"),
        help=_("sample period in seconds (default: the median spacing of t)"),
    )
    # One option per registered setting; each says which methods take it.
    add_setting_options(p.add_argument_group(_("method settings")), settings_of())
    p.add_argument("--json", action="store_true", help=_("print one JSON object"))
    p.add_argument("--plot", metavar="OUT.png", help=_("also save a figure (needs matplotlib)"))
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
                _("{option} does not apply to --method {method} (it applies to {methods})").format(
                    option=option(setting), method=method, methods=", ".join(takers)
                ),
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

    # The note joins the method's warnings (--json, the verdict reads its kind): English, as
    # the library's notes are; library_text says the notes in the user's language.
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
            said = library_text(note)
            print(_("warning: {note}").format(note=said), file=sys.stderr)
            # A warning said in the user's language carries its kind's advice already (as the
            # browser says it); the English note, or one no catalogue knows, gets it below.
            if said == note:
                meaning = _("what it means, what to do: {advice}").format(advice=library_text(what))
                print(f"  {meaning}", file=sys.stderr)
    return 0


def _aligned(rows: list[tuple[str, str]], width: int = 0) -> list[str]:
    """``label  value`` lines, the labels (in the user's language) padded to one width."""
    width = max(width, *(len(label) for label, _value in rows))
    return [f"{label:<{width}}  {value}" for label, value in rows]


def _table(s: dict[str, Any]) -> str:
    method = s["method"]
    lines = _aligned(
        [
            (_("method"), f"{method} ({_label(method)})"),
            (
                _("file"),
                _("{file} ({count} samples, dt = {dt} s)").format(
                    file=s["file"], count=s["n_samples"], dt=decimal(f"{s['dt']:g}")
                ),
            ),
        ]
    )
    if "stats" in s:
        lines += _trajectory_table(s)
        lines += _trust_lines(s)
        return "\n".join(lines)
    un = s.get("units", {})
    u_unit, y_unit = un.get("u", "V"), un.get("y", "V")
    rows = [("K", f"{_num(s['K'])} {un.get('K', '')}".rstrip()), ("tau", f"{_num(s['tau'])} s")]
    if s.get("theta") is not None:
        rows.append((_("theta (dead time)"), f"{_num(s['theta'], '.6g')} s"))
    if method == "srm":
        answer = _("yes") if s["settled"] else _("no")
        rows += [
            (_("K (paper, last sample)"), _num(s["K_last_sample"])),
            (
                _("final value"),
                f"{_num(s['final_value'])} {y_unit} ({_step_word(s['final_value_basis'])})",
            ),
            (_("tau from"), _step_word(s["tau_basis"])),
            (
                _("step"),
                _("{before} -> {after} {unit} at t = {time} s ({direction})").format(
                    before=decimal(f"{s['u_before']:g}"),
                    after=decimal(f"{s['u_after']:g}"),
                    unit=u_unit,
                    time=decimal(f"{s['step_time']:g}"),
                    direction=_step_word(s["direction"]),
                ),
            ),
            (
                _("settled"),
                _("{answer} ({count} time constants recorded)").format(
                    answer=answer, count=decimal(f"{s['time_constants_recorded']:.2f}")
                ),
            ),
        ]
    else:
        if s.get("reason"):
            rows.append((_("not first order"), library_text(s["reason"])))
    if method == "oe":
        rows.append(
            (
                _("fit"),
                _("{simulation} % simulation (record)").format(
                    simulation=_num(s["fit_simulation"], ".2f")
                ),
            )
        )
    elif method != "srm":
        for name, w, se in zip(s["param_names"], s["W"], s["stderr"], strict=True):
            rows.append((name, f"{_num(w)} ± {_num(se)}"))
        held = s.get("fit_holdout")
        figures = {
            "one_step": _num(s["fit_one_step"], ".2f"),
            "simulation": _num(s["fit_simulation"], ".2f"),
        }
        if held is None:
            fit = _("{one_step} % one step, {simulation} % simulation (record)").format(**figures)
        else:
            fit = _(
                "{one_step} % one step, {simulation} % simulation (record), {held_out} % held out"
            ).format(**figures, held_out=_num(held, ".2f"))
        rows.append((_("fit"), fit))
    lines.append("")
    lines += _aligned(rows)
    lines += _trust_lines(s)
    return "\n".join(lines)


def _trajectory_table(s: dict[str, Any]) -> list[str]:
    # The figures the lab's run page shows for the same record (thermolab.ident.table_figures).
    figures = s["figures"]
    tol = decimal(f"±{100 * figures['tol']:g} %")
    conv: dict[str, int | None] | None = figures["converged_at"]
    if figures["over"] == "after_convergence":
        basis = _("(statistics over the {count} samples after convergence, {tolerance})").format(
            count=figures["last"], tolerance=tol
        )
    elif s["stats_over"] == "last":
        basis = _("(statistics over the last {count} samples)").format(count=figures["last"])
    else:
        basis = _(
            "(no convergence within the record: the estimates never stay within {tolerance}; "
            "mean, max and min of the last {count} samples show their scatter)"
        ).format(tolerance=tol, count=figures["last"])
        conv = None
    nan = {"mean": math.nan, "max": math.nan, "min": math.nan}
    stats = {name: figures[name] or nan for name in ("K", "tau")}
    # The columns' titles in the user's language; a longer title widens its column.
    titles = {"final": _("final"), "mean": _("mean"), "max": _("max"), "min": _("min")}
    widths = {key: max(14, len(title)) for key, title in titles.items()}
    converged_at = _("converged at")
    conv_width = max(13, len(converged_at))
    head = f"{'':10} " + " ".join(f"{titles[k]:>{widths[k]}}" for k in titles)
    if conv is not None:
        head += f" {converged_at:>{conv_width}}"
    lines = ["", head]
    for name, label in (("K", "K"), ("tau", "tau (s)")):
        st = stats[name]
        row = f"{label:10} {_num(s[name]):>{widths['final']}} " + " ".join(
            f"{_num(st[k]):>{widths[k]}}" for k in ("mean", "max", "min")
        )
        if conv is not None:
            row += f" {'-' if conv[name] is None else conv[name]:>{conv_width}}"
        lines.append(row)
    lines.append(basis)
    if s.get("theta") is not None:
        delay = _("{theta} s (the order's delay; lsm and oe search it)").format(
            theta=_num(s["theta"], ".6g")
        )
        theta_label = _("theta (dead time)")
        lines.append(f"{theta_label}  {delay}")
    if s.get("reason"):
        lines.append(
            _("final estimate not a first-order model: {reason}").format(
                reason=library_text(s["reason"])
            )
        )
    return lines


def _trust_lines(s: dict[str, Any]) -> list[str]:
    """The operating point, the residual test and the verdict: what a student can trust."""
    labels = {
        "operating_point": _("operating point"),
        "residual_test": _("residual test"),
        "free_run": _("free-run fit"),
        "compared": _("compared with"),
        "trusted": _("trusted"),
    }
    # One width for all five labels, whichever are shown, so every report aligns alike.
    width = max(len(label) for label in labels.values())
    rows: list[tuple[str, str]] = []
    op = s.get("operating_point")
    if op is not None:
        values = {
            "handling": op["handling"],
            "start": _step_word(op["start"]),
            "ambient": _num(op["ambient"], ".6g"),
        }
        reason = library_text(op["reason"])
        if reason == op["reason"] and cli_language() != "en":
            # The library's reasoning has no words but English; as the browser does, the
            # decision is said without it rather than half in English.
            said = _(
                "offset={handling} (decided from the data: record starts {start}, ambient "
                "{ambient})"
            ).format(**values)
        else:
            said = _(
                "offset={handling} (decided from the data: record starts {start}, ambient "
                "{ambient}): {reason}"
            ).format(**values, reason=reason)
        rows.append((labels["operating_point"], said))
    elif s.get("offset") is not None:
        rows.append(
            (labels["operating_point"], _("offset={offset} (given)").format(offset=s["offset"]))
        )
    rt = s.get("residual_test")
    if rt is not None:
        said = _("{verdict} ({whiteness}, {independence}, 99 % bound ±{bound})").format(
            verdict=_("passed") if rt["passed"] else _("FAILED"),
            whiteness=_("whiteness ok") if rt["white"] else _("whiteness failed"),
            independence=(
                _("input independence ok") if rt["independent"] else _("input independence failed")
            ),
            bound=_num(rt["bound"], ".3g"),
        )
        rows.append((labels["residual_test"], said))
    v = s["verdict"]
    if v["fit_record"] is not None:
        said = _("{record} % on the record, {holdout} % on its last third (predicted)").format(
            record=decimal(f"{v['fit_record']:.1f}"), holdout=decimal(f"{v['fit_holdout']:.1f}")
        )
        rows.append((labels["free_run"], said))
    peer = v["agreement"]
    if peer and peer.get("K") is not None:
        rows.append(
            (
                labels["compared"],
                f"{peer['method']}: K {_num(peer['K'], '.4g')}, tau "
                f"{_num(peer['tau'], '.4g')} s, theta {_num(peer['theta'], '.3g')} s",
            )
        )
    rows.append((labels["trusted"], _("yes") if s["trusted"] else _("NO, because:")))
    lines = ["", *_aligned(rows, width)]
    if not s["trusted"]:
        lines += [f"  - {library_text(reason)}" for reason in v["reasons"]]
    return lines


def _num(x: Any, fmt: str = ".6f") -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and (abs(x) >= 1e6 or (x != 0.0 and abs(x) < 1e-4)):
        return decimal(f"{x:.6e}")
    return decimal(f"{x:{fmt}}")


def _save_plot(result: Any, path: str) -> None:
    try:
        fig = result.plot()
    except ImportError as exc:
        raise CliError(f"--plot: {exc}") from None
    try:
        fig.savefig(path)
    except (OSError, ValueError) as exc:
        raise CliError(
            _("--plot: cannot write {path}: {error}").format(path=path, error=exc)
        ) from None


def _positive_float(flag: str) -> Any:
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                _("{option} must be a number, got {value}").format(option=flag, value=repr(text))
            ) from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(
                _("{option} must be finite, got {value}").format(option=flag, value=repr(text))
            )
        if v <= 0:
            raise argparse.ArgumentTypeError(
                _("{option} must be > 0, got {value}").format(option=flag, value=repr(text))
            )
        return v

    return parse


def _label(method: str) -> str:
    """The method's title without its abbreviation: ``"weighted least squares"``, in the
    user's language as the browser's method list names it."""
    from thermolab.web.library_words import method_title

    title = method_title(method, cli_language()) or get_method(method).title
    return title.partition(" (")[0].lower()


def _step_word(value: str) -> str:
    """A word the library names a step's figure or a record's start with (its basis, its
    direction, where the record starts), in the user's language."""
    words = {
        "heating": _("heating"),
        "cooling": _("cooling"),
        "extrapolated": _("extrapolated"),
        "last sample": _("last sample"),
        "63.2% crossing": _("63.2% crossing"),
        "tail fit": _("tail fit"),
        "ambient": _("ambient"),
        "settled": _("settled"),
        "moving": _("moving"),
        "unknown": _("unknown"),
    }
    return words.get(value, value)
