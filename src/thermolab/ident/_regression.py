"""The regression problem ``Y = D W`` built from a record, and its least-squares solution.

Row ``r`` of ``D`` is the regressor of target ``Y[r] = y[t]`` with ``t = lag + 1 + r``
(``lag`` from :attr:`ArxOrder.lag`): ``[y[t-1], ..., y[t-na], u[t-1-delay], ...,
u[t-delay-nb], (1)]``. Every method builds its rows here, so the batch, block,
moving-window and recursive estimates regress exactly the same numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from thermolab.errors import InsufficientExcitationError

from .models import ArxOrder

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True)
class Regression:
    """Regressors and targets of a record, in the frame set by the offset mode."""

    D: FloatArray
    Y: FloatArray
    order: ArxOrder
    constant: bool
    y_shift: float

    @property
    def first_target(self) -> int:
        """Sample index of ``Y[0]``."""
        return self.order.lag + 1

    @property
    def n_params(self) -> int:
        """Number of columns of ``D``."""
        return self.order.na + self.order.nb + int(self.constant)


def offset_shift(offset: str | float, y0: float) -> tuple[float, bool]:
    """``(value subtracted from y, whether a constant column is fitted)``."""
    if offset == "initial":
        return y0, False
    if offset == "fit":
        return 0.0, True
    if offset == "none":
        return 0.0, False
    assert isinstance(offset, float)
    return offset, False


def build(u: FloatArray, y: FloatArray, order: ArxOrder, offset: str | float) -> Regression:
    """Regressor matrix and targets of a whole record (at least ``lag + 2`` samples)."""
    y_shift, constant = offset_shift(offset, float(y[0]))
    ys = y - y_shift if y_shift != 0.0 else y
    n = y.size
    lag = order.lag
    m = n - 1 - lag
    cols = order.na + order.nb + int(constant)
    D = np.empty((m, cols))
    for i in range(order.na):
        D[:, i] = ys[lag - i : lag - i + m]
    for j in range(order.nb):
        start = lag - order.delay - j
        D[:, order.na + j] = u[start : start + m]
    if constant:
        D[:, -1] = 1.0
    return Regression(D, ys[lag + 1 :].copy(), order, constant, y_shift)


class Solution(NamedTuple):
    """A least-squares solution with what the diagnostics need."""

    W: FloatArray  # (..., p) estimates, NaN where rank-deficient
    s: FloatArray  # (..., p) singular values of the equilibrated D, descending
    ok: BoolArray  # (...) True where D has full column rank
    Vt: FloatArray  # (..., p, p) right singular vectors of the equilibrated D
    norms: FloatArray  # (..., p) column norms of D (the equilibration)


def solve(D: FloatArray, Y: FloatArray) -> Solution:
    """Least squares for one problem or a stack of them, by SVD of the equilibrated ``D``.

    ``D`` has shape ``(..., m, p)`` and ``Y`` ``(..., m)``. Columns are scaled to
    unit norm first, so the rank decision and the accuracy do not depend on the
    units of ``u`` and ``y``; no normal equations, no inverse.

    A problem is rank-deficient when a column is zero or the smallest singular
    value of the equilibrated ``D`` is below ``max(m, p) * eps`` times the largest
    (NumPy's ``matrix_rank`` rule).
    """
    # Column norms from the Gram diagonal: one BLAS call, much faster than a
    # strided reduction over the long axis, and as accurate (sums of squares).
    norms = np.sqrt(np.diagonal(np.swapaxes(D, -1, -2) @ D, axis1=-2, axis2=-1))
    safe = np.where(norms > 0.0, norms, 1.0)
    Ds = D / safe[..., None, :]
    U, s, Vt = np.linalg.svd(Ds, full_matrices=False)
    m, p = D.shape[-2], D.shape[-1]
    tol = s[..., :1] * max(m, p) * np.finfo(np.float64).eps
    ok = (s[..., -1:] > tol)[..., 0] & (norms > 0.0).all(axis=-1)
    s_safe = np.where(ok[..., None], s, 1.0)
    beta = (np.swapaxes(U, -1, -2) @ Y[..., None])[..., 0] / s_safe
    W = (np.swapaxes(Vt, -1, -2) @ beta[..., None])[..., 0] / safe
    W[~ok] = np.nan
    return Solution(W, s, ok, Vt, norms)


def excitation_error(reg: Regression, u: FloatArray, s: FloatArray) -> InsufficientExcitationError:
    """The error for a rank-deficient record, saying which column carries no information."""
    scond = s[0] / s[-1] if s[-1] > 0.0 else math.inf
    lead = (
        f"no excitation: the regressor matrix D ({reg.D.shape[0]} rows x {reg.D.shape[1]} "
        f"columns) is rank-deficient (scaled condition number {scond:.3g}), so DᵀD is singular "
        "and eq. 12 has no unique solution"
    )
    if not np.any(u):
        cause = "the input is kept at 0 V throughout"
    elif np.ptp(u) == 0.0:
        cause = f"the input is held constant at {u[0]:.6g} V"
    elif np.ptp(reg.Y) == 0.0 and not reg.constant and reg.Y[0] == 0.0:
        cause = "the output never moves from its initial value"
    elif np.ptp(reg.Y) == 0.0:
        cause = "the output is constant (settled)"
    else:
        cause = "the input and output columns are linearly dependent (output settled)"
    return InsufficientExcitationError(
        f"{lead}: {cause}. Excite the plant: change the input (a step of at least 1 V "
        "or a square wave) while recording."
    )
