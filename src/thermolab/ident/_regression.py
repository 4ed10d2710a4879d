"""The regression problem ``Y = D W`` built from a record, and its least-squares solution.

Row ``r`` of ``D`` is the regressor of target ``Y[r] = y[t]`` with ``t = lag + 1 + r``
(``lag`` from :attr:`ArxOrder.lag`): ``[y[t-1], ..., y[t-na], u[t-1-delay], ...,
u[t-delay-nb], (1)]``. Every method builds its rows here, so the batch, block,
moving-window and recursive estimates regress exactly the same numbers.

Two solvers. :func:`solve` takes ``D`` (or a stack of small ``D``: blocks,
windows) and works on its SVD. :func:`solve_record` solves a whole record
without forming ``D``: it assembles ``[D | Y]`` :data:`CHUNK_ROWS` rows at a
time and folds each chunk into the triangular factor ``R`` of a Householder
QR (LAPACK ``dgeqrf``, a tall-skinny QR), then takes the SVD of the small
``R``. ``D = Q R`` has the singular values of ``R``, and Householder QR is
backward stable column by column, so the solution loses ``cond(D)`` digits
with the columns at any scale, as the SVD of the equilibrated ``D`` does —
never ``cond(D)²`` as the normal equations ``DᵀD`` would (``tests/ident/
test_solvers.py`` checks both against exact rational arithmetic on
ill-conditioned records). On 10⁷ rows it takes 0.1 s and a chunk of memory
where the SVD of ``D`` took 1.5–4 s and three copies of ``D``.
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


#: Rows of ``[D | Y]`` assembled at a time by :func:`solve_record`: small enough
#: for the chunk to stay in the CPU's cache while LAPACK factors it, large
#: enough that the per-call overhead is negligible (16384 rows: 0.08 s for
#: 10⁷ first-order rows here; 4096 and 65536 were slower).
CHUNK_ROWS = 1 << 14


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


def fill_rows(
    u: FloatArray,
    y: FloatArray,
    order: ArxOrder,
    y_shift: float,
    constant: bool,
    lo: int,
    out: FloatArray,
) -> None:
    """Write rows ``lo .. lo + len(out) - 1`` of ``[D | Y]`` into ``out`` (targets last).

    The same numbers as :func:`build` (``y - y_shift`` rounded once), from
    slices of the record.
    """
    m = out.shape[0]
    lag = order.lag
    for i in range(order.na):
        np.subtract(y[lag - i + lo : lag - i + lo + m], y_shift, out=out[:, i])
    for j in range(order.nb):
        start = lag - order.delay - j + lo
        out[:, order.na + j] = u[start : start + m]
    if constant:
        out[:, order.na + order.nb] = 1.0
    np.subtract(y[lag + 1 + lo : lag + 1 + lo + m], y_shift, out=out[:, -1])


def input_drive(u: FloatArray, order: ArxOrder, W: FloatArray, rows: int) -> FloatArray:
    """The input and constant part of ``D W`` (``Σ b_j u[t-1-delay-j] + c``) for ``rows`` rows."""
    start = order.lag - order.delay
    out: FloatArray = np.multiply(W[order.na], u[start : start + rows])
    work = np.empty(rows) if order.nb > 1 else out
    for j in range(1, order.nb):
        start = order.lag - order.delay - j
        out += np.multiply(W[order.na + j], u[start : start + rows], out=work)
    if W.size > order.na + order.nb:
        out += W[-1]
    return out


def predict(
    u: FloatArray, y: FloatArray, order: ArxOrder, y_shift: float, W: FloatArray
) -> FloatArray:
    """``D W`` (the one-step predictions, in the offset frame) without forming ``D``."""
    rows = y.size - 1 - order.lag
    out = input_drive(u, order, W, rows)
    work = np.empty(rows)
    for i in range(order.na):
        start = order.lag - i
        np.subtract(y[start : start + rows], y_shift, out=work)
        out += np.multiply(W[i], work, out=work)
    return out


class RecordSolution(NamedTuple):
    """The least-squares solution of a whole record (:func:`solve_record`)."""

    W: FloatArray  # (p,) estimates, NaN where rank-deficient
    s: FloatArray  # (p,) singular values of the equilibrated D, descending
    ok: bool  # D has full column rank
    Vt: FloatArray  # (p, p) right singular vectors of the equilibrated D
    norms: FloatArray  # (p,) column norms of D
    s_raw: FloatArray  # (p,) singular values of D itself
    rss: float  # ||Y - D W||², from the factorisation (inf where rank-deficient)
    rows: int  # regression rows (targets)
    y_shift: float  # subtracted from y (see offset_shift)
    constant: bool  # a constant column was fitted


def solve_record(
    u: FloatArray, y: FloatArray, order: ArxOrder, offset: str | float
) -> RecordSolution:
    """Least squares over a whole record by a tall-skinny QR of ``[D | Y]`` (see the module).

    Needs at least ``lag + 2`` samples. The rank rule is :func:`solve`'s:
    rank-deficient when a column of ``D`` is zero or the smallest singular
    value of the equilibrated ``D`` is below ``max(m, p) * eps`` times the largest.
    """
    from scipy.linalg import lapack

    y_shift, constant = offset_shift(offset, float(y[0]))
    p = order.na + order.nb + int(constant)
    m = y.size - 1 - order.lag
    # Fortran order: each column of a chunk is contiguous, as LAPACK wants it.
    buf = np.empty((CHUNK_ROWS + p + 1, p + 1), order="F")
    R = np.zeros((0, p + 1))
    below = np.tril_indices(p + 1, -1, p + 1)
    for lo in range(0, m, CHUNK_ROWS):
        rows = min(CHUNK_ROWS, m - lo)
        r = R.shape[0]
        buf[:r] = R
        fill_rows(u, y, order, y_shift, constant, lo, buf[r : r + rows])
        qr, _, _, info = lapack.dgeqrf(buf[: r + rows], overwrite_a=True)
        if info != 0:  # pragma: no cover - only for an invalid argument
            raise RuntimeError(f"LAPACK dgeqrf failed (info = {info})")
        k = min(r + rows, p + 1)
        R = qr[:k].copy()
        R[below[0][below[0] < k], below[1][below[0] < k]] = 0.0  # Householder vectors, not R
    full = np.zeros((p + 1, p + 1))
    full[: R.shape[0]] = R
    RD, z, rho = full[:p, :p], full[:p, p], float(full[p, p])
    norms = np.linalg.norm(RD, axis=0)
    safe = np.where(norms > 0.0, norms, 1.0)
    U, s, Vt = np.linalg.svd(RD / safe)
    tol = s[0] * max(m, p) * np.finfo(np.float64).eps
    ok = bool(s[-1] > tol and (norms > 0.0).all())
    beta = (U.T @ z) / (s if ok else np.ones(p))
    W = (Vt.T @ beta) / safe
    if not ok:
        W[:] = np.nan
    s_raw = np.linalg.svd(RD, compute_uv=False).astype(np.float64)
    rss = rho * rho if ok else math.inf
    return RecordSolution(W, s, ok, Vt, norms, s_raw, rss, m, y_shift, constant)


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


def excitation_error(
    sol: RecordSolution, u: FloatArray, y: FloatArray, order: ArxOrder
) -> InsufficientExcitationError:
    """The error for a rank-deficient record, saying which column carries no information."""
    s = sol.s
    scond = s[0] / s[-1] if s[-1] > 0.0 else math.inf
    targets = y[order.lag + 1 :]
    lead = (
        f"no excitation: the regressor matrix D ({sol.rows} rows x {s.size} "
        f"columns) is rank-deficient (scaled condition number {scond:.3g}), so DᵀD is singular "
        "and eq. 12 has no unique solution"
    )
    if not np.any(u):
        cause = "the input is kept at 0 V throughout"
    elif np.ptp(u) == 0.0:
        cause = f"the input is held constant at {u[0]:.6g} V"
    elif np.ptp(targets) == 0.0 and not sol.constant and targets[0] == sol.y_shift:
        cause = "the output never moves from its initial value"
    elif np.ptp(targets) == 0.0:
        cause = "the output is constant (settled)"
    else:
        cause = "the input and output columns are linearly dependent (output settled)"
    return InsufficientExcitationError(
        f"{lead}: {cause}. Excite the plant: change the input (a step of at least 1 V "
        "or a square wave) while recording."
    )
