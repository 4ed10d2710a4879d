"""Reproduction of the paper's Table I (simulation results).

Every row of Table I is defined here as data (:data:`TABLE1_ROWS`): its input
signal, record length, method and settings, and the figures the paper printed.
:func:`reproduce_table1` runs every row with :mod:`thermolab.ident` on the exact
simulation of the reference model (:data:`thermolab.simulation.REFERENCE_MODEL`)
and returns ours beside the paper's, with the deviation.

The same machinery runs the *variants* that test explanations of the rows the
exact simulation does not reproduce (``docs/reproduction.md`` gives the
experiments and their figures):

* ``solver="explicit-inverse"``: eq. 12 computed verbatim, ``W = (DᵀD)⁻¹DᵀY``
  with an explicit inverse, in double precision (LSM and MALSM rows);
* ``covariance="frozen"``: WLSM with ``P`` held at ``pmax·I`` instead of being
  propagated by eq. 15 (WLSM rows);
* ``noise``, ``quantum``, ``decimals`` and ``precision="float32"``: the
  measured output disturbed by Gaussian noise, quantised (a 16-bit ±10 V DAQ
  has ``quantum = 20/65536`` V), rounded as a spreadsheet file would store it,
  or stored in single precision (every row).

Conventions (decided where the paper is silent, see ``docs/reproduction.md``):

* a record is sampled at ``t = 0, 1, ... s`` with ``y[k]`` read before ``u[k]``
  is applied (:mod:`thermolab.simulation`); the step rows step from 0 to 10 V at
  ``t = 1 s`` (START, then the set point changes), 2000 samples;
* the paper's simulated records start at 0 V, so the methods run with
  ``offset="none"``, the paper's raw regression;
* a WLSM run lasts until 2000 samples after convergence (the paper's
  "duration of 2000 seconds after convergence"): convergence is found on a
  longer pilot record (at least twice the run), the run is cut
  ``after_convergence`` samples after the later of the two convergence samples,
  and the statistics are taken over those last samples.
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidDataError, InvalidParameterError
from thermolab.ident import (
    FIRST_ORDER,
    FirstOrderModel,
    IdentificationWarning,
    Trajectory,
    block_least_squares,
    least_squares,
    moving_window_least_squares,
    step_response,
    weighted_least_squares,
)
from thermolab.ident.registry import PAPER_W0, get_method
from thermolab.jsonsafe import finite_or_none
from thermolab.signals import parse_signal
from thermolab.simulation import REFERENCE_MODEL

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "DAQ_16BIT_QUANTUM",
    "TABLE1_ROWS",
    "Convergence",
    "Figures",
    "RowResult",
    "Stats",
    "Table1Options",
    "Table1Result",
    "Table1Row",
    "reproduce_table1",
]

FloatArray = npt.NDArray[np.float64]
# thermolab.ident.registry.METHOD_NAMES as a type (tests/ident/test_registry.py keeps them equal).
Method = Literal["srm", "lsm", "blockls", "malsm", "wlsm", "oe"]
Solver = Literal["lstsq", "explicit-inverse"]
Covariance = Literal["propagated", "frozen"]
Precision = Literal["float64", "float32"]

#: Quantisation step of the paper's acquisition board, a 16-bit ±10 V DAQ (volts).
DAQ_16BIT_QUANTUM = 20.0 / 65536.0

SOLVERS: tuple[Solver, ...] = ("lstsq", "explicit-inverse")
COVARIANCES: tuple[Covariance, ...] = ("propagated", "frozen")
PRECISIONS: tuple[Precision, ...] = ("float64", "float32")

# The paper prints its figures with 6 decimals.
_PRINTED_DECIMALS = 6
# "The same order of magnitude": within a factor of sqrt(10) either way.
_ORDER_OF_MAGNITUDE = 0.5
# Pilot records for WLSM: start here, double until twice the run fits, stop at the cap.
_PILOT_START = 4096
_PILOT_CAP = 1 << 18
_CONVERGENCE_TOL = 0.01


@dataclass(frozen=True)
class Stats:
    """Mean, maximum and minimum of one parameter over a run.

    Parameters
    ----------
    mean, max, min : float
        The three figures (NaN when there was no valid estimate).

    Examples
    --------
    >>> Stats.single(0.14009).to_dict()
    {'mean': 0.14009, 'max': 0.14009, 'min': 0.14009}
    """

    mean: float
    max: float
    min: float

    @classmethod
    def single(cls, value: float) -> Stats:
        """The statistics of a single estimate (mean = max = min = ``value``).

        Parameters
        ----------
        value : float
            The estimate.

        Returns
        -------
        Stats
            All three fields equal to ``value``.
        """
        return cls(value, value, value)

    @classmethod
    def from_dict(cls, d: dict[str, float]) -> Stats:
        """Build from ``{"mean", "max", "min"}`` (as :meth:`Trajectory.stats` returns).

        Parameters
        ----------
        d : dict
            The three figures by name.

        Returns
        -------
        Stats
            The same figures.
        """
        return cls(float(d["mean"]), float(d["max"]), float(d["min"]))

    def items(self) -> tuple[tuple[str, float], ...]:
        """The three figures with their names, in the paper's order.

        Returns
        -------
        tuple of (str, float)
            ``(("mean", mean), ("max", max), ("min", min))``.
        """
        return (("mean", self.mean), ("max", self.max), ("min", self.min))

    def minus(self, other: Stats) -> Stats:
        """Element-wise ``self - other`` (the deviation from ``other``).

        Parameters
        ----------
        other : Stats
            What to subtract.

        Returns
        -------
        Stats
            The differences.
        """
        return Stats(self.mean - other.mean, self.max - other.max, self.min - other.min)

    def to_dict(self) -> dict[str, float | None]:
        """The figures by name, JSON-safe.

        Returns
        -------
        dict
            ``{"mean", "max", "min"}``; NaN becomes ``None``.
        """
        return {name: finite_or_none(value) for name, value in self.items()}


@dataclass(frozen=True)
class Convergence:
    """Samples until each parameter converged (±1 % of its stabilisation value).

    Parameters
    ----------
    K, tau : int or None
        Sample index of convergence, or None when it did not converge.

    Examples
    --------
    >>> Convergence(54, 73).to_dict()
    {'K': 54, 'tau': 73}
    """

    K: int | None
    tau: int | None

    def to_dict(self) -> dict[str, int | None]:
        """The counts by parameter.

        Returns
        -------
        dict
            ``{"K": int or None, "tau": int or None}``.
        """
        return {"K": self.K, "tau": self.tau}


@dataclass(frozen=True)
class Figures:
    """One row's figures: statistics of ``K`` and ``tau`` and, for WLSM, convergence.

    Parameters
    ----------
    K, tau : Stats
        Mean, maximum and minimum of each parameter.
    converged_at : Convergence or None, optional
        Samples until convergence (WLSM rows only).

    Examples
    --------
    >>> f = Figures(Stats.single(0.140042), Stats.single(250.126233))
    >>> f.to_dict()["K"], f.to_dict()["converged_at"]
    ({'mean': 0.140042, 'max': 0.140042, 'min': 0.140042}, None)
    """

    K: Stats
    tau: Stats
    converged_at: Convergence | None = None

    def to_dict(self) -> dict[str, Any]:
        """The figures as JSON-safe data.

        Returns
        -------
        dict
            ``{"K": {"mean", "max", "min"}, "tau": {...}, "converged_at": {"K", "tau"}
            or None}``.
        """
        return {
            "K": self.K.to_dict(),
            "tau": self.tau.to_dict(),
            "converged_at": None if self.converged_at is None else self.converged_at.to_dict(),
        }


def _paper(
    K: tuple[float, float, float],
    tau: tuple[float, float, float],
    converged: tuple[int, int] | None = None,
) -> Figures:
    return Figures(
        Stats(*K),
        Stats(*tau),
        None if converged is None else Convergence(*converged),
    )


@dataclass(frozen=True)
class Table1Row:
    """The definition of one row of Table I.

    Parameters
    ----------
    run : str
        The paper's name of the run (``"LSM(2)"``).
    method : {"srm", "lsm", "blockls", "malsm", "wlsm"}
        The identification method (:mod:`thermolab.ident`).
    signal : str
        The input, in the syntax of :func:`thermolab.signals.parse_signal`.
    samples : int
        Record length; for WLSM the length of the first pilot record (the run
        itself lasts until ``after_convergence`` samples after convergence).
    paper : Figures
        The figures printed in Table I.
    description : str
        The paper's description of the run.
    block, window : int or None, optional
        Block size (``blockls``) or window (``malsm``) in samples.
    gamma, pmax : float or None, optional
        WLSM forgetting factor and diagonal of the initial ``P`` (paper's form).
    w0 : tuple of float, optional
        WLSM initial parameters; the paper's ``[0.96329, 9.9082e-4]``.

    Examples
    --------
    >>> row = TABLE1_ROWS[5]
    >>> row.run, row.method, row.signal, row.gamma, row.pmax
    ('WLSM(1)', 'wlsm', 'square:0:4:0.1', 0.96, 10000.0)
    """

    run: str
    method: Method
    signal: str
    samples: int
    paper: Figures
    description: str
    block: int | None = None
    window: int | None = None
    gamma: float | None = None
    pmax: float | None = None
    w0: tuple[float, float] = PAPER_W0

    @property
    def slug(self) -> str:
        """A file-name-safe name: ``"LSM(2)"`` -> ``"lsm2"``."""
        return re.sub(r"[^a-z0-9]+", "", self.run.lower())

    def to_dict(self) -> dict[str, Any]:
        """The definition as JSON-safe data (without the paper's figures).

        Returns
        -------
        dict
            ``run``, ``method``, ``signal``, ``samples``, ``description`` and the
            settings that apply (``block``, ``window``, ``gamma``, ``pmax``, ``w0``).
        """
        out: dict[str, Any] = {
            "run": self.run,
            "method": self.method,
            "signal": self.signal,
            "samples": self.samples,
            "description": self.description,
        }
        for name in get_method(self.method).setting_names():
            value = getattr(self, name, None)
            if value is not None:
                out[name] = list(value) if isinstance(value, tuple) else value
        return out


_STEP = "step:0:10@1"
_SQUARE_46 = "square:4:6:0.1"
_SQUARE_04 = "square:0:4:0.1"

#: Every row of the paper's Table I, in the paper's order, with its printed figures.
TABLE1_ROWS: tuple[Table1Row, ...] = (
    Table1Row(
        "SRM",
        "srm",
        _STEP,
        2000,
        _paper((0.140042,) * 3, (250.126233,) * 3),
        "step 0->10 V, 2000 s; gain from the last sample, Ts at 63.2 %",
    ),
    Table1Row(
        "LSM(1)",
        "lsm",
        _STEP,
        2000,
        _paper((0.140090,) * 3, (250.126233,) * 3),
        "step 0->10 V, 2000 s; one estimate from all 2000 samples",
    ),
    Table1Row(
        "LSM(2)",
        "blockls",
        _STEP,
        2000,
        _paper((0.140090, 0.140090, 0.140089), (250.125871, 250.126237, 250.120736)),
        "step 0->10 V, 2000 s; an estimate every 100 samples",
        block=100,
    ),
    Table1Row(
        "LSM(3)",
        "blockls",
        _SQUARE_46,
        2000,
        _paper((0.140090,) * 3, (250.126233,) * 3),
        "square 4<->6 V at 0.1 Hz, 2000 s; an estimate every 100 samples",
        block=100,
    ),
    Table1Row(
        "MALSM",
        "malsm",
        _SQUARE_46,
        2000,
        _paper((0.140090,) * 3, (250.126233,) * 3),
        "square 4<->6 V at 0.1 Hz, 2000 s; moving window of 100 samples",
        window=100,
    ),
    Table1Row(
        "WLSM(1)",
        "wlsm",
        _SQUARE_04,
        _PILOT_START,
        _paper((0.140088, 0.140136, 0.139612), (250.126231, 250.126233, 250.125680), (54, 73)),
        "square 0<->4 V at 0.1 Hz, 2000 s after convergence; gamma 0.96, pmax 1e4",
        gamma=0.96,
        pmax=1e4,
    ),
    Table1Row(
        "WLSM(2)",
        "wlsm",
        _SQUARE_04,
        _PILOT_START,
        _paper((0.140090, 0.140100, 0.139886), (250.126233, 250.126233, 250.126054), (29, 37)),
        "square 0<->4 V at 0.1 Hz, 2000 s after convergence; gamma 0.7, pmax 1e4",
        gamma=0.7,
        pmax=1e4,
    ),
    Table1Row(
        "WLSM(3)",
        "wlsm",
        _SQUARE_04,
        _PILOT_START,
        _paper((0.140086, 0.140101, 0.139015), (250.117447, 250.126233, 247.576412), (108, 109)),
        "square 0<->4 V at 0.1 Hz, 2000 s after convergence; gamma 0.96, pmax 1e3",
        gamma=0.96,
        pmax=1e3,
    ),
    Table1Row(
        "WLSM(4)",
        "wlsm",
        _SQUARE_46,
        _PILOT_START,
        _paper(
            (0.140300, 0.141490, 0.139242),
            (248.661922, 249.362239, 247.636940),
            (9816, 11724),
        ),
        "square 4<->6 V at 0.1 Hz, 2000 s after convergence; gamma 0.96, pmax 1e4",
        gamma=0.96,
        pmax=1e4,
    ),
    Table1Row(
        "WLSM(5)",
        "wlsm",
        _SQUARE_46,
        _PILOT_START,
        _paper(
            (0.140255, 0.141506, 0.139149),
            (248.343654, 248.912988, 247.625883),
            (14981, 18924),
        ),
        "square 4<->6 V at 0.1 Hz, 2000 s after convergence; gamma 0.7, pmax 1e4",
        gamma=0.7,
        pmax=1e4,
    ),
    Table1Row(
        "WLSM(6)",
        "wlsm",
        _SQUARE_46,
        _PILOT_START,
        _paper(
            (0.140333, 0.142151, 0.138689),
            (248.349385, 248.916889, 247.633954),
            (13849, 18933),
        ),
        "square 4<->6 V at 0.1 Hz, 2000 s after convergence; gamma 0.96, pmax 1e3",
        gamma=0.96,
        pmax=1e3,
    ),
)

_RUNS = {row.run: row for row in TABLE1_ROWS}


@dataclass(frozen=True)
class Table1Options:
    """How to run Table I: the exact simulation (the defaults) or a variant of it.

    Parameters
    ----------
    runs : tuple of str, optional
        The rows to run, by the paper's names (default: all, in the paper's order).
    solver : {"lstsq", "explicit-inverse"}, optional
        LSM and MALSM rows: ``"lstsq"`` (default) uses :mod:`thermolab.ident`
        (SVD, no inverse); ``"explicit-inverse"`` computes eq. 12 verbatim,
        ``inv(DᵀD) @ Dᵀ @ Y``, in double precision.
    covariance : {"propagated", "frozen"}, optional
        WLSM rows: ``"propagated"`` (default) runs eqs. 13-15 with
        :func:`~thermolab.ident.weighted_least_squares`; ``"frozen"`` holds ``P``
        at ``pmax·I`` (eq. 15 never applied).
    precision : {"float64", "float32"}, optional
        Store the measured output in single precision (``"float32"``).
    decimals : int or None, optional
        Round the measured output to this many decimals (0 to 15), as a text
        file written with a fixed format would store it.
    quantum : float or None, optional
        Quantise the measured output to multiples of this many volts
        (:data:`DAQ_16BIT_QUANTUM` for the paper's 16-bit ±10 V board).
    noise : float, optional
        Standard deviation (volts) of white Gaussian noise added to the measured
        output. Default 0.
    seed : int, optional
        Seed of the noise (each row draws from its own stream). Default 0.
    after_convergence : int, optional
        Samples a WLSM run lasts after convergence, over which its statistics
        are taken. Default 2000 (the paper's).

    Raises
    ------
    InvalidParameterError
        If an option is outside the values listed here.

    Notes
    -----
    The output disturbances apply in the order noise, quantisation, rounding,
    single precision, to the output only: the input is what the DAQ was told to
    apply, and 0, 4, 6 and 10 V are exact in every format.

    Examples
    --------
    >>> Table1Options(solver="explicit-inverse").describe()
    'solver explicit-inverse'
    >>> Table1Options().describe()
    'exact simulation'
    """

    runs: tuple[str, ...] = tuple(row.run for row in TABLE1_ROWS)
    solver: Solver = "lstsq"
    covariance: Covariance = "propagated"
    precision: Precision = "float64"
    decimals: int | None = None
    quantum: float | None = None
    noise: float = 0.0
    seed: int = 0
    after_convergence: int = 2000

    def __post_init__(self) -> None:
        given: object = self.runs
        runs = (given,) if isinstance(given, str) else tuple(self.runs)
        if not runs:
            raise InvalidParameterError(f"runs must name at least one row: {', '.join(_RUNS)}")
        for run in runs:
            if run not in _RUNS:
                raise InvalidParameterError(f"unknown run {run!r}: Table I has {', '.join(_RUNS)}")
        object.__setattr__(self, "runs", tuple(dict.fromkeys(runs)))
        _choice("solver", self.solver, SOLVERS)
        _choice("covariance", self.covariance, COVARIANCES)
        _choice("precision", self.precision, PRECISIONS)
        if self.decimals is not None:
            _integer("decimals", self.decimals, 0, 15)
        if self.quantum is not None:
            q = _real("quantum", self.quantum)
            if not (math.isfinite(q) and q > 0.0):
                raise InvalidParameterError(
                    f"quantum must be a finite number of volts > 0 "
                    f"(e.g. {DAQ_16BIT_QUANTUM:.6g} for a 16-bit ±10 V DAQ), got {q!r}"
                )
        sigma = _real("noise", self.noise)
        if not (math.isfinite(sigma) and sigma >= 0.0):
            raise InvalidParameterError(
                f"noise must be a finite standard deviation >= 0 volts, got {sigma!r}"
            )
        _integer("seed", self.seed, 0, 2**63 - 1)
        _integer("after_convergence", self.after_convergence, 1, _PILOT_CAP // 4)

    @property
    def disturbs_output(self) -> bool:
        """True when the measured output is not the exact simulation."""
        return (
            self.noise > 0.0
            or self.quantum is not None
            or self.decimals is not None
            or self.precision != "float64"
        )

    def describe(self) -> str:
        """A short text naming every option that differs from the exact simulation.

        Returns
        -------
        str
            ``"exact simulation"`` for the defaults, else the options, comma-separated.
        """
        parts: list[str] = []
        if self.solver != "lstsq":
            parts.append(f"solver {self.solver}")
        if self.covariance != "propagated":
            parts.append(f"covariance {self.covariance}")
        if self.noise > 0.0:
            parts.append(f"noise {self.noise:g} V (seed {self.seed})")
        if self.quantum is not None:
            parts.append(f"quantum {self.quantum:.6g} V")
        if self.decimals is not None:
            parts.append(f"output rounded to {self.decimals} decimals")
        if self.precision != "float64":
            parts.append(f"output stored as {self.precision}")
        if self.after_convergence != 2000:
            parts.append(f"WLSM runs last {self.after_convergence} samples after convergence")
        return ", ".join(parts) or "exact simulation"

    def to_dict(self) -> dict[str, Any]:
        """Every option by name.

        Returns
        -------
        dict
            JSON-safe: ``runs`` (a list), ``solver``, ``covariance``, ``precision``,
            ``decimals``, ``quantum``, ``noise``, ``seed``, ``after_convergence``.
        """
        return {
            "runs": list(self.runs),
            "solver": self.solver,
            "covariance": self.covariance,
            "precision": self.precision,
            "decimals": self.decimals,
            "quantum": self.quantum,
            "noise": self.noise,
            "seed": self.seed,
            "after_convergence": self.after_convergence,
        }


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
            conv = Convergence(_sub(ours_c.K, paper_c.K), _sub(ours_c.tau, paper_c.tau))
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
                value * (1 - _CONVERGENCE_TOL),
                value * (1 + _CONVERGENCE_TOL),
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

    def format(self) -> str:
        """A readable table: ours beside the paper's figures, with the deviation.

        Returns
        -------
        str
            One line per figure; the last column says ``=`` when ours rounds to
            the paper's printed digits, ``~`` when a convergence count is within
            a factor of √10 of the paper's, and ``x`` otherwise.
        """
        lines = [
            "Table I (simulation): ours on the reference model "
            f"(Ks = {REFERENCE_MODEL.K:.6f}, Ts = {REFERENCE_MODEL.tau:.6f} s, "
            f"T = {REFERENCE_MODEL.dt:g} s) beside the paper's printed figures",
            f"variant: {self.options.describe()}",
            "",
            f"{'run':<8} {'param':<5} {'stat':<5} {'ours':>13} {'paper':>13} {'ours - paper':>13}",
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
                        f"{r.run if first else '':<8} {pname:<5} "
                        f"{'value' if single else stat:<5} {_number(ours):>13} "
                        f"{_number(paper):>13} {_number(ours - paper, sign=True):>13} {mark}"
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
                    dev_n = _sub(ours_n, paper_n)
                    lines.append(
                        f"{'':<8} {pname:<5} {'conv':<5} {_int_text(ours_n):>13} "
                        f"{_int_text(paper_n):>13} "
                        f"{'-' if dev_n is None else f'{dev_n:+d}':>13} {mark}"
                    )
            for note in r.notes:
                lines.append(f"{'':<8} note: {note}")
        lines += [
            "",
            "= ours rounds to the paper's printed digits; ~ samples to converge within a "
            "factor of 3.2 of the paper's; x differs (see docs/reproduction.md)",
            "conv: samples until the estimate stays within ±1 % of its stabilisation value; "
            "WLSM statistics over the "
            f"{_samples(self.options.after_convergence)} after convergence",
        ]
        digits = [r.run for r in self.rows if r.digits_match]
        order = [r.run for r in self.rows if r.convergence_order_match]
        lines.append(
            f"match to the printed digits: {', '.join(digits) or 'none'}; "
            f"convergence within the order of magnitude: {', '.join(order) or 'none'}"
        )
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


def reproduce_table1(
    *,
    runs: Sequence[str] | None = None,
    solver: Solver = "lstsq",
    covariance: Covariance = "propagated",
    precision: Precision = "float64",
    decimals: int | None = None,
    quantum: float | None = None,
    noise: float = 0.0,
    seed: int = 0,
    after_convergence: int = 2000,
) -> Table1Result:
    """Run the rows of the paper's Table I on the simulated reference model.

    Parameters
    ----------
    runs : sequence of str, optional
        Rows to run by the paper's names (default: all eleven).
    solver, covariance, precision, decimals, quantum, noise, seed, after_convergence
        The variant to run; see :class:`Table1Options`. The defaults are the
        exact double-precision simulation with the library's methods.

    Returns
    -------
    Table1Result
        Ours beside the paper's figures, row by row.

    Raises
    ------
    InvalidParameterError
        If an option is not allowed (an unknown run, a negative noise ...).

    Notes
    -----
    Every row simulates the reference model (Ks = 0.140090, Ts = 250.126233 s,
    T = 1 s) exactly (:func:`thermolab.simulation.simulate_first_order`) on
    its input signal, disturbs the measured output if asked, and runs the
    row's method. The whole table takes a second or two (the first run in a
    fresh installation also compiles the Numba kernels of
    :mod:`thermolab.ident`).

    Examples
    --------
    >>> result = reproduce_table1(runs=["SRM", "LSM(1)", "MALSM"])
    >>> [(r.run, r.digits_match) for r in result.rows]
    [('SRM', True), ('LSM(1)', True), ('MALSM', True)]
    >>> round(result.row("SRM").ours.K.mean, 6), round(result.row("SRM").ours.tau.mean, 6)
    (0.140042, 250.126233)

    The explicit inverse of eq. 12 is what moves the paper's LSM(2) off the
    exact value, by milliseconds on the late, ill-conditioned blocks:

    >>> exact = reproduce_table1(runs=["LSM(2)"]).rows[0].ours.tau
    >>> inverse = reproduce_table1(runs=["LSM(2)"], solver="explicit-inverse").rows[0].ours.tau
    >>> abs(exact.min - 250.126233) < 1e-6, 1e-4 < abs(inverse.min - 250.126233) < 1e-1
    (True, True)
    """
    options = Table1Options(
        runs=tuple(_RUNS) if runs is None else _as_runs(runs),
        solver=solver,
        covariance=covariance,
        precision=precision,
        decimals=decimals,
        quantum=quantum,
        noise=noise,
        seed=seed,
        after_convergence=after_convergence,
    )
    rows = [_RUNS[run] for run in options.runs]
    results = tuple(_run_row(row, options) for row in rows)
    return Table1Result(results, options)


# --- running one row ---------------------------------------------------------------


def _run_row(row: Table1Row, options: Table1Options) -> RowResult:
    try:
        return _run_method(row, options)
    except InvalidDataError as exc:
        if not options.disturbs_output:
            raise  # the exact simulation must always be identifiable: a bug, say so
        # Under heavy noise or coarse quantisation a method may refuse the record;
        # that is a finding of the variant, reported in its row.
        none = Stats.single(math.nan)
        conv = Convergence(None, None) if row.method == "wlsm" else None
        return RowResult(row, Figures(none, none, conv), row.samples, (f"no estimate: {exc}",))


def _run_method(row: Table1Row, options: Table1Options) -> RowResult:
    with warnings.catch_warnings():
        # A disturbed record may trip the methods' checks; the notes keep them.
        warnings.simplefilter("ignore", IdentificationWarning)
        return _run_method_quietly(row, options)


def _run_method_quietly(row: Table1Row, options: Table1Options) -> RowResult:
    index = list(_RUNS).index(row.run)
    if row.method == "wlsm":
        return _run_wlsm(row, options, index)
    t, u, y = _record(row, row.samples, options, index)
    dt = REFERENCE_MODEL.dt
    if row.method == "srm":
        with warnings.catch_warnings():
            # A disturbed record may trip the method's checks; the notes keep them.
            warnings.simplefilter("ignore", IdentificationWarning)
            srm = step_response(t, u, y)
        # The paper's SRM gain is the last sample; its Ts the 63.2 % crossing.
        figures = Figures(Stats.single(srm.K_last_sample), Stats.single(srm.tau))
        notes = (
            *srm.warnings,
            f"settled (extrapolated) gain {srm.K:.6f}; the paper's figure is the last sample",
        )
        return RowResult(row, figures, t.size, notes, detail=srm)
    if row.method == "lsm":
        if options.solver == "explicit-inverse":
            W = _explicit_inverse(u[:-1, None], y[:-1, None], y[1:, None])[0]
            model = FirstOrderModel.from_discrete(float(W[0]), float(W[1]), dt)
            figures = Figures(Stats.single(model.K), Stats.single(model.tau))
            return RowResult(row, figures, t.size, _model_notes(model))
        # The paper's eq. 4 model: no dead time search.
        lsm = least_squares(u, y, dt, order=FIRST_ORDER, offset="none")
        figures = Figures(Stats.single(lsm.K), Stats.single(lsm.tau))
        notes = (*_model_notes(lsm.model), *lsm.warnings)
        return RowResult(row, figures, t.size, notes, detail=lsm)
    if row.method == "blockls":
        assert row.block is not None
        if options.solver == "explicit-inverse":
            tr = _explicit_inverse_blocks(u, y, dt, row.block)
        else:
            tr = block_least_squares(u, y, dt, row.block, order=FIRST_ORDER, offset="none")
    else:
        assert row.window is not None
        if options.solver == "explicit-inverse":
            tr = _explicit_inverse_windows(u, y, dt, row.window)
        else:
            tr = moving_window_least_squares(u, y, dt, row.window, order=FIRST_ORDER, offset="none")
    stats = tr.stats(last=tr.n_samples)
    figures = Figures(Stats.from_dict(stats["K"]), Stats.from_dict(stats["tau"]))
    return RowResult(row, figures, t.size, _trajectory_notes(tr), trajectory=tr)


def _run_wlsm(row: Table1Row, options: Table1Options, index: int) -> RowResult:
    after = options.after_convergence
    n = max(row.samples, 2 * (after + 1))
    while True:
        _, u, y = _record(row, n, options, index)
        tr = _wlsm(row, options, u, y)
        conv = tr.converged_at(tol=_CONVERGENCE_TOL, last=after)
        at = None if conv["K"] is None or conv["tau"] is None else max(conv["K"], conv["tau"])
        if at is not None and 2 * (at + after + 1) <= n:
            break
        if n >= _PILOT_CAP:
            break
        n = min(2 * n, _PILOT_CAP)
    notes: list[str] = []
    if at is not None and at + after + 1 <= n:
        length = at + after + 1
        cut = Trajectory(
            tr.method,
            tr.dt,
            tr.W[:length],
            tr.order,
            tr.offset,
            tr.param_names,
            None if tr.status is None else tr.status[:length],
            tr.params,
        )
    else:
        length, cut = n, tr
        # "Converging" inside the very samples that define the stabilisation value
        # is no convergence: report it as none.
        conv = {name: None if k is None or k > n - after else k for name, k in conv.items()}
        notes.append(
            f"did not converge within {n} samples (±1 % of the mean of the last {after}); "
            f"statistics over the last {after} samples of the {n}"
        )
    stats = cut.stats(last=after)
    figures = Figures(
        Stats.from_dict(stats["K"]),
        Stats.from_dict(stats["tau"]),
        Convergence(conv["K"], conv["tau"]),
    )
    return RowResult(row, figures, length, tuple(notes) + _trajectory_notes(cut), trajectory=cut)


def _wlsm(row: Table1Row, options: Table1Options, u: FloatArray, y: FloatArray) -> Trajectory:
    assert row.gamma is not None
    assert row.pmax is not None
    dt = REFERENCE_MODEL.dt
    if options.covariance == "frozen":
        return _frozen_covariance_wlsm(u, y, dt, row.gamma, row.pmax, row.w0)
    return weighted_least_squares(
        u, y, dt, row.gamma, row.pmax, row.w0, form="paper", order=FIRST_ORDER, offset="none"
    )


def _record(
    row: Table1Row, n: int, options: Table1Options, index: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The row's input and its simulated (and possibly disturbed) output, ``n`` samples."""
    dt = REFERENCE_MODEL.dt
    t = np.arange(n, dtype=np.float64) * dt
    u = parse_signal(row.signal).sample(t)
    y = REFERENCE_MODEL.simulate(u)
    if options.noise > 0.0:
        # Each row draws from its own stream, so running a subset changes nothing.
        rng = np.random.default_rng([options.seed, index])
        y = y + rng.normal(0.0, options.noise, size=n)
    if options.quantum is not None:
        y = np.round(y / options.quantum) * options.quantum
    if options.decimals is not None:
        y = np.round(y, options.decimals)
    if options.precision == "float32":
        y = y.astype(np.float32).astype(np.float64)
    return t, u, y


# --- the variants' arithmetic ---------------------------------------------------------


def _explicit_inverse(u: FloatArray, y: FloatArray, target: FloatArray) -> FloatArray:
    """Eq. 12 verbatim for each column set: ``W = inv(DᵀD) @ Dᵀ @ Y`` with ``D = [y, u]``.

    ``u``, ``y`` and ``target`` have shape ``(rows, n_sets)``; returns ``(n_sets, 2)``.
    Each set is solved by itself (a 2x2 ``inv`` and two matrix products, in the
    printed order), so the rounding is that of the formula, not of a batched kernel.
    """
    n_sets = u.shape[1]
    W = np.full((n_sets, 2), np.nan)
    for j in range(n_sets):
        D = np.column_stack([y[:, j], u[:, j]])
        try:
            W[j] = np.linalg.inv(D.T @ D) @ D.T @ target[:, j]
        except np.linalg.LinAlgError:
            continue  # exactly singular: no estimate, as the trajectory reports
    return W


def _explicit_inverse_blocks(u: FloatArray, y: FloatArray, dt: float, block: int) -> Trajectory:
    """LSM(2)/(3) with eq. 12 verbatim, on the same blocks and rows as ``block_least_squares``."""
    rows = block - 1
    n_blocks = y.size // block
    starts = np.arange(n_blocks) * block
    idx = starts[None, :] + np.arange(rows)[:, None]
    W = np.full((y.size, 2), np.nan)
    W[starts + block - 1] = _explicit_inverse(u[idx], y[idx], y[idx + 1])
    return _trajectory("blockls", dt, W, {"block": block, "solver": "explicit-inverse"})


def _explicit_inverse_windows(u: FloatArray, y: FloatArray, dt: float, window: int) -> Trajectory:
    """MALSM with eq. 12 verbatim, on the same windows as ``moving_window_least_squares``."""
    rows = window - 1
    ends = np.arange(window - 1, y.size)
    idx = (ends - window + 1)[None, :] + np.arange(rows)[:, None]
    W = np.full((y.size, 2), np.nan)
    W[ends] = _explicit_inverse(u[idx], y[idx], y[idx + 1])
    return _trajectory("malsm", dt, W, {"window": window, "solver": "explicit-inverse"})


def _frozen_covariance_wlsm(
    u: FloatArray, y: FloatArray, dt: float, gamma: float, pmax: float, w0: Iterable[float]
) -> Trajectory:
    """Eqs. 13-14 of the paper with ``P`` held at ``pmax·I`` (eq. 15 never applied).

    With ``P = pmax·I`` the gain of eq. 13 is ``c D / (1/α + c |D|²)``, ``c = pmax/γ``:
    a normalised-gradient step along the regressor, whose convergence depends on
    how far the regressor's directions are apart, unlike recursive least squares.
    Rows are aligned as in ``weighted_least_squares``: ``W0`` at sample 0, then the
    estimate updated with the row whose target is sample ``k``.
    """
    c = pmax / gamma
    inv_alpha = 1.0 / (1.0 - gamma)
    a, b = (float(v) for v in w0)
    yl = y.tolist()
    ul = u.tolist()
    out = np.empty((y.size, 2))
    out[0] = (a, b)
    for k in range(1, y.size):
        d0, d1 = yl[k - 1], ul[k - 1]
        gain = c / (inv_alpha + c * (d0 * d0 + d1 * d1))
        err = yl[k] - (a * d0 + b * d1)
        a += gain * d0 * err
        b += gain * d1 * err
        out[k, 0] = a
        out[k, 1] = b
    params = {"gamma": gamma, "pmax": pmax, "form": "paper", "covariance": "frozen"}
    return _trajectory("wlsm", dt, out, params)


def _trajectory(method: str, dt: float, W: FloatArray, params: dict[str, Any]) -> Trajectory:
    return Trajectory(method, dt, W, FIRST_ORDER, "none", FIRST_ORDER.param_names(), params=params)


# --- small helpers --------------------------------------------------------------------


def _model_notes(model: FirstOrderModel) -> tuple[str, ...]:
    return () if model.valid else (f"no first-order model: {model.reason}",)


def _trajectory_notes(tr: Trajectory) -> tuple[str, ...]:
    return (*_invalid_notes(tr), *tr.warnings)


def _invalid_notes(tr: Trajectory) -> tuple[str, ...]:
    has = ~np.isnan(tr.W).all(axis=1)
    bad = has & ~tr.valid
    if not bad.any():
        return ()
    first = int(np.flatnonzero(bad)[0])
    return (
        f"{int(bad.sum())} of {int(has.sum())} estimates have no first-order meaning "
        f"(first at sample {first}: {tr.invalid_reason[first]}); statistics over the others",
    )


def _printed(x: float) -> float:
    return round(x, _PRINTED_DECIMALS) if math.isfinite(x) else x


def _same_order(ours: int | None, paper: int | None) -> bool:
    if ours is None or paper is None or ours <= 0 or paper <= 0:
        return False
    return abs(math.log10(ours / paper)) <= _ORDER_OF_MAGNITUDE


def _sub(a: int | None, b: int | None) -> int | None:
    return None if a is None or b is None else a - b


def _number(x: float, *, sign: bool = False) -> str:
    """Six decimals like the paper; ``-`` for no figure; exponent form when huge."""
    if not math.isfinite(x):
        return "-"
    if abs(x) < 5e-7:
        x = 0.0  # prints as +0.000000, not -0.000000
    if abs(x) >= 1e7:
        return f"{x:+.6e}" if sign else f"{x:.6e}"
    return f"{x:+.6f}" if sign else f"{x:.6f}"


def _samples(n: int) -> str:
    return f"{n} sample{'' if n == 1 else 's'}"


def _int_text(n: int | None) -> str:
    return "-" if n is None else str(n)


def _as_runs(runs: Sequence[str]) -> tuple[str, ...]:
    if isinstance(runs, str):
        return (runs,)
    return tuple(runs)


def _choice(name: str, value: object, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise InvalidParameterError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")


def _real(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidParameterError(f"{name} must be a number, got {value!r}")
    return float(value)


def _integer(name: str, value: object, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InvalidParameterError(f"{name} must be an integer, got {value!r}")
    v = int(value)
    if not lo <= v <= hi:
        raise InvalidParameterError(f"{name} must be between {lo} and {hi}, got {v}")
    return v
