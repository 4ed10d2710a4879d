"""Figures for identification results; matplotlib is imported only here, when asked for.

Figures are built with :class:`matplotlib.figure.Figure`, not pyplot, so plotting
touches no global state and works in a server thread or a test without a display.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .lsm_result import LeastSquaresResult
    from .models import FirstOrderModel
    from .trajectory import Trajectory

_NAMES = {
    "blockls": "block least squares",
    "malsm": "moving-window least squares",
    "wlsm": "weighted least squares",
    "lsm": "least squares",
    "srm": "step response",
}


def _figure() -> Figure:
    try:
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImportError("plotting needs matplotlib: pip install 'thermolab[plot]'") from exc
    return Figure(figsize=(8.0, 5.5), layout="constrained")


def plot_trajectory(
    tr: Trajectory, *, reference: FirstOrderModel | None, title: str | None
) -> Figure:
    """Two stacked panels, ``K`` and ``tau`` against the sample index."""
    fig = _figure()
    ax_k, ax_tau = fig.subplots(2, 1, sharex=True)
    k = tr.k
    style = {"marker": "o", "markersize": 3, "linestyle": "none"} if tr.method == "blockls" else {}
    ax_k.plot(k, tr.K, color="tab:blue", label="estimate", **style)
    ax_tau.plot(k, tr.tau, color="tab:red", label="estimate", **style)
    if reference is not None and reference.valid:
        ax_k.axhline(reference.K, color="k", linestyle="--", linewidth=1, label="reference")
        ax_tau.axhline(reference.tau, color="k", linestyle="--", linewidth=1, label="reference")
    ax_k.set_ylabel("K (V/V)")
    ax_tau.set_ylabel("tau (s)")
    ax_tau.set_xlabel(f"sample k (dt = {tr.dt:g} s)")
    for ax in (ax_k, ax_tau):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
    settings = ", ".join(
        f"{name}={value!s}" for name, value in tr.params.items() if np.isscalar(value)
    )
    fig.suptitle(title or f"{_NAMES.get(tr.method, tr.method)} ({settings})")
    return fig


def plot_least_squares(res: LeastSquaresResult, *, title: str | None) -> Figure:
    """Measured output with the one-step prediction and the free-run simulation."""
    fig = _figure()
    ax_y, ax_r = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1))
    ax_y.plot(res.k, res.y_measured, color="k", linewidth=1, label="measured")
    ax_y.plot(res.k, res.y_one_step, color="tab:blue", linewidth=1, label="one-step prediction")
    ax_y.plot(res.k, res.y_simulated, color="tab:red", linewidth=1, label="free-run simulation")
    ax_r.plot(res.k, res.residuals, color="tab:blue", linewidth=1)
    ax_y.set_ylabel("y (V)")
    ax_r.set_ylabel("residual (V)")
    ax_r.set_xlabel(f"sample k (dt = {res.dt:g} s)")
    for ax in (ax_y, ax_r):
        ax.grid(True, alpha=0.3)
    ax_y.legend(loc="best")
    fig.suptitle(
        title
        or f"least squares: K = {res.K:.6g}, tau = {res.tau:.6g} s, fit {res.fit_one_step:.1f} % "
        f"(one step), {res.fit_simulation:.1f} % (simulation)"
    )
    return fig
