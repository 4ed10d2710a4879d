"""The figures of the paper's Tables I/II for each method of a run.

Computed once, when a run ends, and stored with the method's result; runs
stored before the lab kept them were given theirs by the migration
``v0003_method_statistics`` (:func:`replay_statistics`), never on a read.
"""

from __future__ import annotations

import math
from typing import Any

from thermolab.errors import ThermoLabError
from thermolab.ident.online import OnlineIdentifier, make_identifier
from thermolab.ident.table_figures import table_figures

__all__ = ["CONVERGENCE_TOL", "STATS_LAST", "method_statistics", "replay_statistics"]

#: The paper's tables: convergence within ±1 %; a scatter's spread over the last 2000 samples.
STATS_LAST = 2000
CONVERGENCE_TOL = 0.01

# Methods with one estimate per sample or block (a trajectory that converges).
_TRAJECTORY_METHODS = ("blockls", "malsm", "wlsm")


def method_statistics(
    method: str, identifier: OnlineIdentifier | None, latest: dict[str, Any] | None
) -> dict[str, Any]:
    """The figures of the paper's Tables I/II for one method of a run.

    Parameters
    ----------
    method : str
        The method's name.
    identifier : OnlineIdentifier or None
        The run's identifier (its trajectory gives the statistics of the block
        and recursive methods).
    latest : dict or None
        The method's latest estimate as stored (``Estimate.to_dict()``); the
        one estimate of SRM and LSM.

    Returns
    -------
    dict
        ``{"last", "tol", "K", "tau", "converged_at"}``: ``K`` and ``tau`` are
        ``{"mean", "max", "min"}``, ``None`` without a valid estimate. Block
        and recursive methods' come from :func:`thermolab.ident.table_figures.table_figures`,
        the function ``thermolab identify`` prints a CSV record's with, so the
        run's CSV gives the same figures there (issue #24): over the samples
        after convergence within ± :data:`CONVERGENCE_TOL` (``over``:
        ``"after_convergence"``, ``last`` of them), or, where the estimates
        never converge, their spread over the last :data:`STATS_LAST` samples
        (``over``: ``"last"``); ``converged_at`` the samples to converge
        (``None`` for one that did not) and ``converged`` the paper's verdict.
        SRM and LSM give their one estimate as mean, max and min and no
        ``converged_at`` (one estimate does not converge).

    Examples
    --------
    >>> method_statistics("lsm", None, {"K": 0.14, "tau": 250.0, "valid": True})["K"]
    {'mean': 0.14, 'max': 0.14, 'min': 0.14}
    """
    out: dict[str, Any] = {
        "last": STATS_LAST,
        "tol": CONVERGENCE_TOL,
        "K": None,
        "tau": None,
        "converged_at": None,
    }
    if method in _TRAJECTORY_METHODS:
        if identifier is None or identifier.n_samples == 0:
            return out
        figures = table_figures(identifier.trajectory(), tol=CONVERGENCE_TOL, spread=STATS_LAST)
        # The page never shows the estimate of a run that did not converge as final.
        return {**out, **figures}
    if latest is not None and latest.get("valid"):
        for name in ("K", "tau"):
            value = latest.get(name)
            if isinstance(value, float | int) and math.isfinite(value):
                out[name] = {"mean": float(value), "max": float(value), "min": float(value)}
    return out


def replay_statistics(
    method: str,
    dt: float,
    params: dict[str, Any],
    latest: dict[str, Any] | None,
    samples: list[tuple[float, float]],
) -> dict[str, Any]:
    """The statistics of a stored method, by running it again over the run's samples.

    The identifiers are deterministic, so this is the trajectory the run had.

    Raises
    ------
    ThermoLabError
        If the stored settings no longer make an identifier.
    """
    identifier: OnlineIdentifier | None = None
    if method in _TRAJECTORY_METHODS:
        identifier = make_identifier(method, dt, **params)
        for u, y in samples:
            try:
                identifier.update(u, y)
            except ThermoLabError:
                break  # where the run's identifier stopped too
    return method_statistics(method, identifier, latest)
