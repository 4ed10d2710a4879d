"""A recursive or windowed method's figures for the paper's Tables I/II: one rule everywhere.

``thermolab identify`` prints them for a CSV record and the lab stores them
when a run ends (its run page and its comparison show them), so the same
record gives the same figures in both (issue #24): :func:`table_figures` is
the one function that decides which samples the mean, maximum and minimum
cover and how many samples the estimates took to converge.

The paper's count (the default): the statistics cover the samples *after*
convergence (:meth:`~thermolab.ident.Trajectory.after_convergence`), so a
record only a little longer than the transient does not average its
start-up in (WLSM(1) on the paper's 2000 samples: over the whole record Ks
is 1.5 % low and "never converges"; after convergence it converges at
samples 86/87 and Ks is 0.140080). Estimates that never converge scatter:
their spread over the last ``spread`` samples is what a student reads then.
Asking for ``last`` gives the statistics over the last ``last`` samples and
:meth:`~thermolab.ident.Trajectory.converged_at`'s count instead.
"""

from __future__ import annotations

import math
from typing import Any

from .trajectory import Trajectory

__all__ = ["SPREAD_LAST", "table_figures"]

#: The samples whose spread a record that never converges shows (the paper's tables: 2000).
SPREAD_LAST = 2000


def table_figures(
    trajectory: Trajectory, *, tol: float = 0.01, last: int | None = None, spread: int = SPREAD_LAST
) -> dict[str, Any]:
    """The figures of a trajectory as the paper's tables give them, JSON-ready.

    Parameters
    ----------
    trajectory : Trajectory
        A recursive, windowed or block method's estimates.
    tol : float, optional
        The convergence band, relative (default 0.01: ±1 %).
    last : int, optional
        Statistics over the last ``last`` samples instead of the paper's count.
    spread : int, optional
        The last samples whose spread a record that never converges shows.

    Returns
    -------
    dict
        ``over`` (``"after_convergence"`` or ``"last"``: what the statistics
        cover), ``tol``, ``last`` (how many samples they cover), ``converged``
        (the paper's verdict, :meth:`~thermolab.ident.Trajectory.after_convergence`),
        ``converged_at`` (``{"K", "tau"}``: the samples to converge, ``None``
        where they did not), ``K`` and ``tau`` (``{"mean", "max", "min"}`` or
        ``None`` without a valid estimate).

    Examples
    --------
    >>> import numpy as np
    >>> from thermolab.ident import ArxOrder
    >>> a = np.r_[np.linspace(0.5, 0.9, 50), np.full(100, 0.9)]
    >>> W = np.column_stack([a, 0.2 * (1 - a)])
    >>> f = table_figures(Trajectory("wlsm", 1.0, W, ArxOrder(), "initial", ("a", "b")))
    >>> f["over"], f["converged_at"], f["last"], round(f["K"]["mean"], 6)
    ('after_convergence', {'K': 0, 'tau': 49}, 100, 0.2)
    """
    after = trajectory.after_convergence(tol)
    converged = bool(after["converged"])
    if last is not None:
        stats = trajectory.stats(last)
        at = trajectory.converged_at(tol, last)
        over, covered = "last", min(last, trajectory.n_samples)
    elif converged:
        stats, at = after["stats"], after["converged_at"]
        over, covered = "after_convergence", int(after["samples_after"])
    else:
        # No convergence: the scatter of the last samples, and no count.
        stats, at = trajectory.stats(spread), {"K": None, "tau": None}
        over, covered = "last", min(spread, trajectory.n_samples)
    return {
        "over": over,
        "tol": tol,
        "last": covered,
        "converged": converged,
        "converged_at": dict(at),
        "K": _stat(stats["K"]),
        "tau": _stat(stats["tau"]),
    }


def _stat(s: dict[str, float]) -> dict[str, float] | None:
    values = {key: float(s[key]) for key in ("mean", "max", "min")}
    return values if all(math.isfinite(v) for v in values.values()) else None
