"""How to run Table I: :class:`Table1Options`, the exact simulation or a variant of it."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from thermolab.errors import InvalidParameterError

from ._table import RUNS, TABLE1_ROWS

__all__ = [
    "COVARIANCES",
    "DAQ_16BIT_QUANTUM",
    "PILOT_CAP",
    "PRECISIONS",
    "SOLVERS",
    "Covariance",
    "Precision",
    "Solver",
    "Table1Options",
]

Solver = Literal["lstsq", "explicit-inverse"]
Covariance = Literal["propagated", "frozen"]
Precision = Literal["float64", "float32"]

#: Quantisation step of the paper's acquisition board, a 16-bit ±10 V DAQ (volts).
DAQ_16BIT_QUANTUM = 20.0 / 65536.0

SOLVERS: tuple[Solver, ...] = ("lstsq", "explicit-inverse")
COVARIANCES: tuple[Covariance, ...] = ("propagated", "frozen")
PRECISIONS: tuple[Precision, ...] = ("float64", "float32")

# The longest WLSM pilot record (see _running); bounds ``after_convergence``.
PILOT_CAP = 1 << 18


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
            raise InvalidParameterError(f"runs must name at least one row: {', '.join(RUNS)}")
        for run in runs:
            if run not in RUNS:
                raise InvalidParameterError(f"unknown run {run!r}: Table I has {', '.join(RUNS)}")
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
        _integer("after_convergence", self.after_convergence, 1, PILOT_CAP // 4)

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
