"""The figures of a Table I row: mean/max/min statistics and convergence counts.

What the paper printed and what we compute share these shapes
(:class:`Figures`); :mod:`thermolab.reproduction` re-exports them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from thermolab.jsonsafe import finite_or_none

__all__ = ["CONVERGENCE_TOL", "Convergence", "Figures", "Stats", "sub"]

#: Converged: within ±1 % of the stabilisation value (the paper's rule).
CONVERGENCE_TOL = 0.01


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


def sub(a: int | None, b: int | None) -> int | None:
    """``a - b`` for two counts, None when either is missing."""
    return None if a is None or b is None else a - b
