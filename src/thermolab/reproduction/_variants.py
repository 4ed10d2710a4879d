"""The variants' arithmetic: eq. 12 with an explicit inverse, WLSM with a frozen covariance.

Used by :mod:`thermolab.reproduction._running` when :class:`Table1Options` asks
for ``solver="explicit-inverse"`` or ``covariance="frozen"``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.ident import FIRST_ORDER, Trajectory

__all__ = [
    "explicit_inverse",
    "explicit_inverse_blocks",
    "explicit_inverse_windows",
    "frozen_covariance_wlsm",
]

FloatArray = npt.NDArray[np.float64]


def explicit_inverse(u: FloatArray, y: FloatArray, target: FloatArray) -> FloatArray:
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


def explicit_inverse_blocks(u: FloatArray, y: FloatArray, dt: float, block: int) -> Trajectory:
    """LSM(2)/(3) with eq. 12 verbatim, on the same blocks and rows as ``block_least_squares``."""
    rows = block - 1
    n_blocks = y.size // block
    starts = np.arange(n_blocks) * block
    idx = starts[None, :] + np.arange(rows)[:, None]
    W = np.full((y.size, 2), np.nan)
    W[starts + block - 1] = explicit_inverse(u[idx], y[idx], y[idx + 1])
    return _trajectory("blockls", dt, W, {"block": block, "solver": "explicit-inverse"})


def explicit_inverse_windows(u: FloatArray, y: FloatArray, dt: float, window: int) -> Trajectory:
    """MALSM with eq. 12 verbatim, on the same windows as ``moving_window_least_squares``."""
    rows = window - 1
    ends = np.arange(window - 1, y.size)
    idx = (ends - window + 1)[None, :] + np.arange(rows)[:, None]
    W = np.full((y.size, 2), np.nan)
    W[ends] = explicit_inverse(u[idx], y[idx], y[idx + 1])
    return _trajectory("malsm", dt, W, {"window": window, "solver": "explicit-inverse"})


def frozen_covariance_wlsm(
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
