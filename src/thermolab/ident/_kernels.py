"""Numba-compiled kernels of the recursive methods: scalar loops, no allocation per sample.

Each method has a *step* function that consumes one regression row and updates
a state held in preallocated arrays, and a *run* function that loops the step
over a whole record. The online identifiers call the very same step functions
from Python, so a sample fed online gives bit-for-bit the estimate of the batch
run.

Status codes returned per row follow :data:`thermolab.ident.models.INVALID_REASONS`:
0 an estimate was made, 1 no estimate yet, 2 the window's regression is
singular, 6 the recursion produced a non-finite number.

Moving window (MALSM)
---------------------
The window's normal equations ``DᵀD W = DᵀY`` are kept as running sums,
updated by adding the newest row and subtracting the one leaving the FIFO:
O(p²) per sample whatever the window length. Two measures keep them honest:

* sums are accumulated about a shift (the column means of the window at the
  last recomputation), so they carry the *variation* of the data and not its
  level — a 2.5 V ambient with millivolt changes does not lose the millivolts
  to cancellation;
* every ``recompute_every`` rows (default: the window's row count) the sums
  are recomputed from the window's rows, so rounding cannot drift: the cost
  stays O(p²) per sample amortised.

``DᵀD`` is rebuilt from the shifted sums, equilibrated to unit diagonal and
solved (Cholesky in general, Cramer's rule for first order). A window whose
equilibrated ``DᵀD`` has a pivot below ``RCOND_MIN`` (condition number above
about 1e12) is reported singular.

Accuracy. Normal equations square the condition number: for a window whose
regressor matrix (columns scaled to unit norm) has condition number ``κ``,
the estimate agrees with a QR/SVD solve of that window to about
``κ² · ρ · 1e-16`` relative, where ``ρ >= 1`` is how much larger (squared)
the values that went through the running sums since the last recomputation
were than the window's own mean square — about 1 for data at a steady level,
larger when a small window follows large swings. That is 1e-14 for the
paper's square-wave windows (κ ≈ 8), 1e-8 for a nearly settled step
(κ ≈ 1e4). The tests check this bound on every window.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
CodeArray = npt.NDArray[np.int8]

#: Smallest Cholesky pivot of the equilibrated normal matrix accepted as non-singular.
RCOND_MIN = 1e-12

# Layout of the MALSM ``ints`` state array.
_COUNT, _HEAD, _SINCE, _EVERY = 0, 1, 2, 3
# Layout of the first-order MALSM ``acc`` state (:mod:`._kernels_first_order`): shifted
# sums, then the shifts.
ACC2_SIZE = 11


@njit(cache=True, error_model="numpy")
def fill_row(
    u: FloatArray,
    ys: FloatArray,
    t: int,
    na: int,
    nb: int,
    delay: int,
    const: bool,
    row: FloatArray,
) -> None:
    """Regressor of target ``ys[t]``: ``[ys[t-1..t-na], u[t-1-delay..t-delay-nb], (1)]``."""
    for i in range(na):
        row[i] = ys[t - 1 - i]
    for j in range(nb):
        row[na + j] = u[t - 1 - delay - j]
    if const:
        row[na + nb] = 1.0


@njit(cache=True, error_model="numpy")
def _malsm_recompute(buf: FloatArray, sums: FloatArray, shift: FloatArray) -> None:
    """Fresh sums of the window's rows about their column means (in buffer order)."""
    L = buf.shape[0]
    q = buf.shape[1]  # p regressors + the target
    p = q - 1
    for c in range(q):
        acc = 0.0
        for r in range(L):
            acc += buf[r, c]
        shift[c] = acc / L
    for k in range(sums.shape[0]):
        sums[k] = 0.0
    for idx in range(L):
        for i in range(p):
            di = buf[idx, i] - shift[i]
            sums[i] += di
            for j in range(i, p):
                sums[q + i * p + j] += di * (buf[idx, j] - shift[j])
            sums[q + p * p + i] += di * (buf[idx, p] - shift[p])
        sums[p] += buf[idx, p] - shift[p]


@njit(cache=True, error_model="numpy")
def _malsm_accumulate(
    buf: FloatArray, sums: FloatArray, shift: FloatArray, idx: int, sign: float
) -> None:
    """Add (sign = 1) or remove (sign = -1) row ``idx`` of the window to the shifted sums."""
    q = buf.shape[1]
    p = q - 1
    dt_ = buf[idx, p] - shift[p]
    for i in range(p):
        di = buf[idx, i] - shift[i]
        sums[i] += sign * di
        for j in range(i, p):
            sums[q + i * p + j] += sign * (di * (buf[idx, j] - shift[j]))
        sums[q + p * p + i] += sign * (di * dt_)
    sums[p] += sign * dt_


@njit(cache=True, error_model="numpy")
def _malsm_solve(
    sums: FloatArray, shift: FloatArray, L: int, work: FloatArray, W: FloatArray
) -> int:
    """Solve the window's normal equations rebuilt from the shifted sums; 0 or 2 (singular)."""
    p = W.shape[0]
    q = p + 1
    st = shift[p]
    m_off = 0  # work[0 : p*p] holds the equilibrated matrix, then its Cholesky factor
    g_off = p * p  # work[g_off : g_off+p] the right-hand side, then the solution
    d_off = p * p + p  # work[d_off : d_off+p] the equilibration
    for i in range(p):
        si = shift[i]
        for j in range(i, p):
            sj = shift[j]
            mij = sums[q + i * p + j] + sums[i] * sj + si * sums[j] + L * si * sj
            work[m_off + i * p + j] = mij
            work[m_off + j * p + i] = mij
        work[g_off + i] = sums[q + p * p + i] + sums[i] * st + si * sums[p] + L * si * st
    for i in range(p):
        dii = work[m_off + i * p + i]
        if not dii > 0.0:
            return 2
        work[d_off + i] = 1.0 / np.sqrt(dii)
    for i in range(p):
        di = work[d_off + i]
        work[g_off + i] *= di
        for j in range(p):
            work[m_off + i * p + j] *= di * work[d_off + j]
    # Cholesky of the equilibrated matrix (lower factor in place).
    for j in range(p):
        pivot = work[m_off + j * p + j]
        for k in range(j):
            pivot -= work[m_off + j * p + k] * work[m_off + j * p + k]
        if not pivot > RCOND_MIN:
            return 2
        ljj = np.sqrt(pivot)
        work[m_off + j * p + j] = ljj
        for i in range(j + 1, p):
            acc = work[m_off + i * p + j]
            for k in range(j):
                acc -= work[m_off + i * p + k] * work[m_off + j * p + k]
            work[m_off + i * p + j] = acc / ljj
    for i in range(p):  # forward substitution L z = g
        acc = work[g_off + i]
        for k in range(i):
            acc -= work[m_off + i * p + k] * work[g_off + k]
        work[g_off + i] = acc / work[m_off + i * p + i]
    for i in range(p - 1, -1, -1):  # back substitution Lᵀ x = z
        acc = work[g_off + i]
        for k in range(i + 1, p):
            acc -= work[m_off + k * p + i] * work[g_off + k]
        work[g_off + i] = acc / work[m_off + i * p + i]
    for i in range(p):
        W[i] = work[g_off + i] * work[d_off + i]
    return 0


@njit(cache=True, error_model="numpy")
def malsm_push(
    buf: FloatArray,
    sums: FloatArray,
    shift: FloatArray,
    ints: IntArray,
    row: FloatArray,
    target: float,
    work: FloatArray,
    W: FloatArray,
) -> int:
    """Push one regression row into the FIFO window; solve once the window is full.

    Returns the status code: 1 (window not full yet), 0 (``W`` updated) or 2 (singular).
    """
    L = buf.shape[0]
    p = row.shape[0]
    count = ints[_COUNT]
    head = ints[_HEAD]
    if count >= L:
        _malsm_accumulate(buf, sums, shift, head, -1.0)
    for i in range(p):
        buf[head, i] = row[i]
    buf[head, p] = target
    if count >= L:
        _malsm_accumulate(buf, sums, shift, head, 1.0)
    head += 1
    if head == L:
        head = 0
    count += 1
    ints[_COUNT] = count
    ints[_HEAD] = head
    if count < L:
        return 1
    ints[_SINCE] += 1
    if count == L or ints[_SINCE] >= ints[_EVERY]:
        _malsm_recompute(buf, sums, shift)
        ints[_SINCE] = 0
    return _malsm_solve(sums, shift, L, work, W)


@njit(cache=True, error_model="numpy")
def malsm_chunk(
    u: FloatArray,
    ys: FloatArray,
    start: int,
    stop: int,
    na: int,
    nb: int,
    delay: int,
    const: bool,
    buf: FloatArray,
    sums: FloatArray,
    shift: FloatArray,
    ints: IntArray,
    W_out: FloatArray,
    code_out: CodeArray,
) -> None:
    """MALSM for targets ``ys[start:stop]``; row ``t`` of the outputs gets target ``t``'s result."""
    p = shift.shape[0] - 1
    row = np.empty(p)
    work = np.empty(p * p + 2 * p)
    W = np.empty(p)
    for t in range(start, stop):
        fill_row(u, ys, t, na, nb, delay, const, row)
        status = malsm_push(buf, sums, shift, ints, row, ys[t], work, W)
        code_out[t] = status
        for i in range(p):
            W_out[t, i] = W[i] if status == 0 else np.nan


@njit(cache=True, error_model="numpy")
def wlsm_paper_step(
    W: FloatArray, P: FloatArray, row: FloatArray, target: float, gamma: float, work: FloatArray
) -> int:
    """One step of the paper's eqs. 13-15, literally; returns 0, or 6 if non-finite.

    ``α = 1 - γ``; ``K = (P/γ) D (1/α + Dᵀ (P/γ) D)⁻¹``; ``W ← W + K (y - DᵀW)``;
    ``P ← (1/γ) (I - K Dᵀ) P``.
    """
    p = W.shape[0]
    alpha = 1.0 - gamma
    # work[0:p] = (P/γ) D, work[p:2p] = K, work[2p:3p] = Dᵀ P
    denom = 1.0 / alpha
    for i in range(p):
        acc = 0.0
        for j in range(p):
            acc += (P[i, j] / gamma) * row[j]
        work[i] = acc
        denom += row[i] * acc
    for i in range(p):
        work[p + i] = work[i] / denom
    err = target
    for i in range(p):
        err -= row[i] * W[i]
    for i in range(p):
        W[i] += work[p + i] * err
    for j in range(p):
        acc = 0.0
        for i in range(p):
            acc += row[i] * P[i, j]
        work[2 * p + j] = acc
    finite = True
    for i in range(p):
        for j in range(p):
            P[i, j] = (P[i, j] - work[p + i] * work[2 * p + j]) / gamma
            if not np.isfinite(P[i, j]):
                finite = False
        if not np.isfinite(W[i]):
            finite = False
    return 0 if finite else 6


@njit(cache=True, error_model="numpy")
def wlsm_standard_step(
    W: FloatArray, P: FloatArray, row: FloatArray, target: float, gamma: float, work: FloatArray
) -> int:
    """One step of exponential-forgetting RLS; returns 0, or 6 if non-finite.

    ``K = P D / (γ + Dᵀ P D)``; ``W ← W + K (y - DᵀW)``; ``P ← (P - K DᵀP) / γ``,
    with ``P`` kept exactly symmetric.
    """
    p = W.shape[0]
    denom = gamma
    for i in range(p):
        acc = 0.0
        for j in range(p):
            acc += P[i, j] * row[j]
        work[i] = acc
        denom += row[i] * acc
    for i in range(p):
        work[p + i] = work[i] / denom
    err = target
    for i in range(p):
        err -= row[i] * W[i]
    for i in range(p):
        W[i] += work[p + i] * err
    finite = True
    for i in range(p):
        for j in range(i, p):
            v = (P[i, j] - work[p + i] * work[j]) / gamma
            P[i, j] = v
            P[j, i] = v
            if not np.isfinite(v):
                finite = False
        if not np.isfinite(W[i]):
            finite = False
    return 0 if finite else 6


@njit(cache=True, error_model="numpy")
def wlsm_chunk(
    u: FloatArray,
    ys: FloatArray,
    start: int,
    stop: int,
    na: int,
    nb: int,
    delay: int,
    const: bool,
    paper: bool,
    gamma: float,
    W: FloatArray,
    P: FloatArray,
    W_out: FloatArray,
    code_out: CodeArray,
) -> None:
    """WLSM for targets ``ys[start:stop]``, updating ``W`` and ``P`` in place.

    Once the recursion has produced a non-finite number it stops: that row and
    every later one get status 6.
    """
    p = W.shape[0]
    row = np.empty(p)
    work = np.empty(3 * p)
    alive = bool(np.isfinite(W).all() and np.isfinite(P).all())
    for t in range(start, stop):
        if not alive:
            code_out[t] = 6
            for i in range(p):
                W_out[t, i] = np.nan
            continue
        fill_row(u, ys, t, na, nb, delay, const, row)
        if paper:
            status = wlsm_paper_step(W, P, row, ys[t], gamma, work)
        else:
            status = wlsm_standard_step(W, P, row, ys[t], gamma, work)
        code_out[t] = status
        if status != 0:
            alive = False
        for i in range(p):
            W_out[t, i] = W[i] if status == 0 else np.nan


def malsm_state(
    rows: int, every: int, n_params: int, first_order: bool
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray]:
    """Fresh MALSM state ``(buf, sums, shift, ints)``; first order uses ``sums`` as ``acc``."""
    ints = np.zeros(4, dtype=np.int64)
    ints[_EVERY] = every
    p = n_params
    buf = np.zeros((rows, p + 1))
    sums = np.zeros(ACC2_SIZE if first_order else p + 1 + p * p + p)
    return buf, sums, np.zeros(p + 1), ints
