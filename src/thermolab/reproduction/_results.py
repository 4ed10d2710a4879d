"""Table I as we ran it: each row beside the paper's figures, as text, data and plots."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from thermolab.errors import InvalidParameterError
from thermolab.ident import FirstOrderModel, Trajectory
from thermolab.ident.registry import get_method
from thermolab.simulation import REFERENCE_MODEL

from ._figures import CONVERGENCE_TOL, Convergence, Figures, sub
from ._options import Table1Options
from ._table import Table1Row

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["RowResult", "Table1Result"]

# The paper prints its figures with 6 decimals.
_PRINTED_DECIMALS = 6
# "The same order of magnitude": within a factor of sqrt(10) either way.
_ORDER_OF_MAGNITUDE = 0.5


@dataclass(frozen=True, eq=False)
class RowResult:
    """One row of Table I as we ran it, beside the paper's figures.

    Attributes
    ----------
    row : Table1Row
        The row's definition (with ``row.paper``, the printed figures).
    ours : Figures
        Our figures.
    samples : int
        Length of the record the figures come from (for WLSM: the run, cut
        ``after_convergence`` samples after convergence).
    notes : tuple of str
        Anything that qualifies the figures (a run that did not converge ...).
    trajectory : Trajectory or None
        The estimates of the block and recursive rows (for plots).
    detail : object or None
        The single-estimate result (SRM: ``StepResponseResult``; LSM(1) with the
        default solver: ``LeastSquaresResult``), for plots.

    Examples
    --------
    >>> from thermolab.reproduction import reproduce_table1
    >>> r = reproduce_table1(runs=["LSM(3)"]).rows[0]
    >>> r.run, r.digits_match, round(r.ours.tau.min, 6), r.paper.tau.min
    ('LSM(3)', True, 250.126233, 250.126233)
    >>> r.deviation.tau.max < 1e-6
    True
    """

    row: Table1Row
    ours: Figures
    samples: int
    notes: tuple[str, ...] = ()
    trajectory: Trajectory | None = field(default=None, repr=False)
    detail: Any = field(default=None, repr=False)

    @property
    def run(self) -> str:
        """The paper's name of the row."""
        return self.row.run

    @property
    def paper(self) -> Figures:
        """The figures printed in Table I."""
        return self.row.paper

    @property
    def deviation(self) -> Figures:
        """Ours minus the paper's, figure by figure (convergence in samples)."""
        conv: Convergence | None = None
        ours_c, paper_c = self.ours.converged_at, self.paper.converged_at
        if ours_c is not None and paper_c is not None:
            conv = Convergence(sub(ours_c.K, paper_c.K), sub(ours_c.tau, paper_c.tau))
        return Figures(self.ours.K.minus(self.paper.K), self.ours.tau.minus(self.paper.tau), conv)

    @property
    def digits_match(self) -> bool:
        """True when all six figures, rounded to the paper's 6 decimals, equal the paper's."""
        return all(
            _printed(ours) == paper
            for ours_s, paper_s in (
                (self.ours.K, self.paper.K),
                (self.ours.tau, self.paper.tau),
            )
            for (_, ours), (_, paper) in zip(ours_s.items(), paper_s.items(), strict=True)
        )

    @property
    def convergence_order_match(self) -> bool | None:
        """For WLSM rows: both convergence counts within a factor of √10 of the paper's.

        None for rows without a convergence figure.
        """
        ours_c, paper_c = self.ours.converged_at, self.paper.converged_at
        if ours_c is None or paper_c is None:
            return None
        return _same_order(ours_c.K, paper_c.K) and _same_order(ours_c.tau, paper_c.tau)

    def to_dict(self) -> dict[str, Any]:
        """The row in the command line's JSON shape.

        Returns
        -------
        dict
            ``run``, ``K``, ``tau``, ``converged_at`` (ours), ``paper`` (the same
            shape), ``deviation`` (ours - paper), ``agreement``
            (``{"digits": bool, "convergence_order": bool or None}``),
            ``samples``, ``notes`` and ``definition`` (the row's input and method).
        """
        ours = self.ours.to_dict()
        return {
            "run": self.run,
            "K": ours["K"],
            "tau": ours["tau"],
            "converged_at": ours["converged_at"],
            "paper": self.paper.to_dict(),
            "deviation": self.deviation.to_dict(),
            "agreement": {
                "digits": self.digits_match,
                "convergence_order": self.convergence_order_match,
            },
            "samples": self.samples,
            "notes": list(self.notes),
            "definition": self.row.to_dict(),
        }

    def plot(self) -> Figure | None:
        """Parameter convergence (block and recursive rows) or the fit (SRM, LSM(1)).

        Returns
        -------
        matplotlib.figure.Figure or None
            Like the paper's Figs. 9-11 for trajectories: ``K`` and ``tau`` against
            the sample, the reference model dashed, the paper's ±1 % band around
            it and the convergence samples marked. None when the row kept nothing
            to plot (LSM(1) with the explicit-inverse solver).

        Raises
        ------
        ImportError
            If matplotlib is not installed (``pip install 'thermolab[plot]'``).
        """
        title = f"Table I, {self.run}: {self.row.description}"
        if self.trajectory is None:
            if self.detail is None:
                return None
            fig: Figure = self.detail.plot(title=title)
            return fig
        ref = FirstOrderModel(REFERENCE_MODEL.K, REFERENCE_MODEL.tau)
        fig = self.trajectory.plot(reference=ref, title=title)
        ax_k, ax_tau = fig.axes[0], fig.axes[1]
        conv = self.ours.converged_at
        for ax, value, at in (
            (ax_k, ref.K, None if conv is None else conv.K),
            (ax_tau, ref.tau, None if conv is None else conv.tau),
        ):
            ax.axhspan(
                value * (1 - CONVERGENCE_TOL),
                value * (1 + CONVERGENCE_TOL),
                color="0.85",
                zorder=0,
                label="±1 % of the reference",
            )
            if at is not None:
                ax.axvline(at, color="tab:green", linewidth=1, label=f"converged at {at}")
            ax.legend(loc="best")
        return fig


@dataclass(frozen=True, eq=False)
class Table1Result:
    """Table I as we ran it: one :class:`RowResult` per row, and the options used.

    Attributes
    ----------
    rows : tuple of RowResult
        In the paper's order.
    options : Table1Options
        How the rows were run.

    Examples
    --------
    >>> from thermolab.reproduction import reproduce_table1
    >>> result = reproduce_table1(runs=["SRM", "WLSM(2)"])
    >>> print(result.format().splitlines()[4])
    SRM      Ks    value      0.140042      0.140042     +0.000000 =
    >>> result.to_dict()["rows"][1]["paper"]["converged_at"]
    {'K': 29, 'tau': 37}
    """

    rows: tuple[RowResult, ...]
    options: Table1Options

    def row(self, run: str) -> RowResult:
        """The result of one row by its paper name.

        Parameters
        ----------
        run : str
            ``"SRM"``, ``"LSM(1)"`` ... ``"WLSM(6)"``.

        Returns
        -------
        RowResult
            That row.

        Raises
        ------
        InvalidParameterError
            If the row was not run.
        """
        for r in self.rows:
            if r.run == run:
                return r
        ran = ", ".join(r.run for r in self.rows)
        raise InvalidParameterError(f"row {run!r} was not run; this result has {ran}")

    def to_dict(self) -> dict[str, Any]:
        """The table as JSON-safe data (the shape ``thermolab reproduce table1 --json`` prints).

        Returns
        -------
        dict
            ``{"rows": [...], "options": {...}, "variant": str, "reference_model":
            {"K", "tau", "dt"}}``. Each row is :meth:`RowResult.to_dict`: ``run``,
            ``K`` and ``tau`` (``{"mean", "max", "min"}``), ``converged_at``
            (``{"K", "tau"}`` or None), ``paper`` in the same shape, and the
            deviation and agreement.
        """
        return {
            "rows": [r.to_dict() for r in self.rows],
            "options": self.options.to_dict(),
            "variant": self.options.describe(),
            "reference_model": {
                "K": REFERENCE_MODEL.K,
                "tau": REFERENCE_MODEL.tau,
                "dt": REFERENCE_MODEL.dt,
            },
        }

    def format(self, say: Callable[[str], str] | None = None) -> str:
        """A readable table: ours beside the paper's figures, with the deviation.

        Parameters
        ----------
        say
            Says the table's words and sentences in a reader's language (the
            command line's translator): each English phrase given to it is a
            msgid, and the variant and the notes are given as the library wrote
            them. The figures, their marks, the rows' names and the symbols are
            never given. Default: English.

        Returns
        -------
        str
            One line per figure; the last column says ``=`` when ours rounds to
            the paper's printed digits, ``~`` when a convergence count is within
            a factor of √10 of the paper's, and ``x`` otherwise. The columns are
            as wide as their words in the reader's language need.
        """
        if say is None:
            say = _english
        heads = [say("run"), say("param"), say("stat"), say("ours"), say("paper")]
        heads.append(say("ours - paper"))
        stats = {"mean": say("mean"), "max": say("max"), "min": say("min")}
        value, conv = say("value"), say("conv")
        w_run = max(8, len(heads[0]))
        w_par = max(5, len(heads[1]))
        w_stat = max(5, len(heads[2]), len(value), len(conv), *(len(w) for w in stats.values()))
        w_num = max(13, *(len(h) for h in heads[3:]))
        lines = [
            say(
                "Table I (simulation): ours on the reference model "
                "(Ks = {K}, Ts = {tau} s, T = {dt} s) beside the paper's printed figures"
            ).format(
                K=f"{REFERENCE_MODEL.K:.6f}",
                tau=f"{REFERENCE_MODEL.tau:.6f}",
                dt=f"{REFERENCE_MODEL.dt:g}",
            ),
            say("variant: {variant}").format(variant=say(self.options.describe())),
            "",
            f"{heads[0]:<{w_run}} {heads[1]:<{w_par}} {heads[2]:<{w_stat}} "
            f"{heads[3]:>{w_num}} {heads[4]:>{w_num}} {heads[5]:>{w_num}}",
        ]
        for r in self.rows:
            single = "trajectory" not in get_method(r.row.method).returns
            first = True
            for pname, ours_s, paper_s in (
                ("Ks", r.ours.K, r.paper.K),
                ("Ts", r.ours.tau, r.paper.tau),
            ):
                items = list(zip(ours_s.items(), paper_s.items(), strict=True))
                for (stat, ours), (_, paper) in items[:1] if single else items:
                    mark = "=" if _printed(ours) == paper else "x"
                    lines.append(
                        f"{r.run if first else '':<{w_run}} {pname:<{w_par}} "
                        f"{value if single else stats[stat]:<{w_stat}} {_number(ours):>{w_num}} "
                        f"{_number(paper):>{w_num}} {_number(ours - paper, sign=True):>{w_num}} "
                        f"{mark}"
                    )
                    first = False
                    pname = ""
            ours_c, paper_c = r.ours.converged_at, r.paper.converged_at
            if paper_c is not None:
                for pname, ours_n, paper_n in (
                    ("Ks", None if ours_c is None else ours_c.K, paper_c.K),
                    ("Ts", None if ours_c is None else ours_c.tau, paper_c.tau),
                ):
                    mark = "~" if _same_order(ours_n, paper_n) else "x"
                    dev_n = sub(ours_n, paper_n)
                    lines.append(
                        f"{'':<{w_run}} {pname:<{w_par}} {conv:<{w_stat}} "
                        f"{_int_text(ours_n):>{w_num}} {_int_text(paper_n):>{w_num}} "
                        f"{'-' if dev_n is None else f'{dev_n:+d}':>{w_num}} {mark}"
                    )
            for note in r.notes:
                lines.append(f"{'':<{w_run}} " + say("note: {note}").format(note=say(note)))
        after = self.options.after_convergence
        if after == 1:
            window = say(
                "conv: samples until the estimate stays within ±1 % of its stabilisation "
                "value; WLSM statistics over the {count} sample after convergence"
            )
        else:
            window = say(
                "conv: samples until the estimate stays within ±1 % of its stabilisation "
                "value; WLSM statistics over the {count} samples after convergence"
            )
        digits = [r.run for r in self.rows if r.digits_match]
        order = [r.run for r in self.rows if r.convergence_order_match]
        none = say("none")
        lines += [
            "",
            say(
                "= ours rounds to the paper's printed digits; ~ samples to converge within a "
                "factor of 3.2 of the paper's; x differs (see docs/reproduction.md)"
            ),
            window.format(count=after),
            say(
                "match to the printed digits: {digits}; "
                "convergence within the order of magnitude: {order}"
            ).format(digits=", ".join(digits) or none, order=", ".join(order) or none),
        ]
        return "\n".join(lines)

    def plot(self, directory: str | Path) -> list[Path]:
        """Write one PNG figure per row into ``directory`` (created if missing).

        Parameters
        ----------
        directory : str or pathlib.Path
            Where to write ``table1-<run>.png`` (``table1-wlsm2.png`` ...).

        Returns
        -------
        list of pathlib.Path
            The files written, in the rows' order.

        Raises
        ------
        ImportError
            If matplotlib is not installed (``pip install 'thermolab[plot]'``).
        OSError
            If the directory cannot be created or written.
        """
        out_dir = Path(directory)
        out_dir.mkdir(parents=True, exist_ok=True)
        written: list[Path] = []
        for r in self.rows:
            fig = r.plot()
            if fig is None:
                continue
            path = out_dir / f"table1-{r.row.slug}.png"
            fig.savefig(path, dpi=100)
            written.append(path)
        return written


def _printed(x: float) -> float:
    return round(x, _PRINTED_DECIMALS) if math.isfinite(x) else x


def _same_order(ours: int | None, paper: int | None) -> bool:
    if ours is None or paper is None or ours <= 0 or paper <= 0:
        return False
    return abs(math.log10(ours / paper)) <= _ORDER_OF_MAGNITUDE


def _number(x: float, *, sign: bool = False) -> str:
    """Six decimals like the paper; ``-`` for no figure; exponent form when huge."""
    if not math.isfinite(x):
        return "-"
    if abs(x) < 5e-7:
        x = 0.0  # prints as +0.000000, not -0.000000
    if abs(x) >= 1e7:
        return f"{x:+.6e}" if sign else f"{x:.6e}"
    return f"{x:+.6f}" if sign else f"{x:.6f}"


def _english(text: str) -> str:
    """The table's words as written (no translation)."""
    return text


def _int_text(n: int | None) -> str:
    return "-" if n is None else str(n)
