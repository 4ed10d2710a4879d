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


# ---------------------------------------------------------------------------
# First order (eq. 4, W = [a, b], no constant term): the same algorithms with the
# 2x2 algebra written out and the state held in local variables for the length
# of a chunk, which is what the runner and the paper's tables use. (Held in
# arrays between samples, the state's loads and stores would be serialised by
# possible aliasing and cost ten times the arithmetic.)
# ---------------------------------------------------------------------------

# Layout of the first-order MALSM ``acc`` state: shifted sums, then the shifts.
ACC2_SIZE = 11


@njit(cache=True, error_model="numpy")
def _malsm2_sums(
    buf: FloatArray,
) -> tuple[float, float, float, float, float, float, float, float, float, float, float]:
    """Sums of the window's rows about their column means (the exact recomputation)."""
    L = buf.shape[0]
    m1 = 0.0
    m2 = 0.0
    mt = 0.0
    for r in range(L):
        m1 += buf[r, 0]
        m2 += buf[r, 1]
        mt += buf[r, 2]
    h1 = m1 / L
    h2 = m2 / L
    ht = mt / L
    s1 = s2 = st = s11 = s12 = s22 = s1t = s2t = 0.0
    for r in range(L):
        d1 = buf[r, 0] - h1
        d2 = buf[r, 1] - h2
        dt_ = buf[r, 2] - ht
        s1 += d1
        s2 += d2
        st += dt_
        s11 += d1 * d1
        s12 += d1 * d2
        s22 += d2 * d2
        s1t += d1 * dt_
        s2t += d2 * dt_
    return s1, s2, st, s11, s12, s22, s1t, s2t, h1, h2, ht


@njit(cache=True, error_model="numpy")
def malsm2_chunk(
    u: FloatArray,
    ys: FloatArray,
    start: int,
    stop: int,
    buf: FloatArray,
    acc: FloatArray,
    ints: IntArray,
    W_out: FloatArray,
    code_out: CodeArray,
) -> tuple[int, float, float]:
    """First-order MALSM for targets ``ys[start:stop]`` (row ``[ys[t-1], u[t-1]]``).

    ``buf`` (rows x 3) is the FIFO of ``[y[k], u[k], y[k+1]]``; ``acc`` holds
    the shifted sums ``S1 S2 St S11 S12 S22 S1t S2t`` and the shifts ``h1 h2 ht``;
    ``ints`` the counters. The 2x2 normal equations are solved by Cramer's rule;
    the window is singular when ``det <= RCOND_MIN * M11 * M22`` (the general
    kernel's equilibrated pivot test). Returns the last row's ``(status, a, b)``,
    which spares the online identifier three array reads per sample.
    """
    L = buf.shape[0]
    status = 1
    wa = np.nan
    wb = np.nan
    count = ints[_COUNT]
    head = ints[_HEAD]
    since = ints[_SINCE]
    every = ints[_EVERY]
    s1, s2, st = acc[0], acc[1], acc[2]
    s11, s12, s22, s1t, s2t = acc[3], acc[4], acc[5], acc[6], acc[7]
    h1, h2, ht = acc[8], acc[9], acc[10]
    for t in range(start, stop):
        x1 = ys[t - 1]
        x2 = u[t - 1]
        target = ys[t]
        if count >= L:
            o1 = buf[head, 0] - h1
            o2 = buf[head, 1] - h2
            ot = buf[head, 2] - ht
            n1 = x1 - h1
            n2 = x2 - h2
            nt = target - ht
            s1 += n1 - o1
            s2 += n2 - o2
            st += nt - ot
            s11 += n1 * n1 - o1 * o1
            s12 += n1 * n2 - o1 * o2
            s22 += n2 * n2 - o2 * o2
            s1t += n1 * nt - o1 * ot
            s2t += n2 * nt - o2 * ot
        buf[head, 0] = x1
        buf[head, 1] = x2
        buf[head, 2] = target
        head += 1
        if head == L:
            head = 0
        count += 1
        if count < L:
            status = 1
            wa = np.nan
            wb = np.nan
            code_out[t] = 1
            W_out[t, 0] = np.nan
            W_out[t, 1] = np.nan
            continue
        since += 1
        if count == L or since >= every:
            s1, s2, st, s11, s12, s22, s1t, s2t, h1, h2, ht = _malsm2_sums(buf)
            since = 0
        m11 = s11 + 2.0 * s1 * h1 + L * h1 * h1
        m12 = s12 + s1 * h2 + h1 * s2 + L * h1 * h2
        m22 = s22 + 2.0 * s2 * h2 + L * h2 * h2
        g1 = s1t + s1 * ht + h1 * st + L * h1 * ht
        g2 = s2t + s2 * ht + h2 * st + L * h2 * ht
        det = m11 * m22 - m12 * m12
        if m11 > 0.0 and m22 > 0.0 and det > RCOND_MIN * (m11 * m22):
            inv = 1.0 / det
            status = 0
            wa = (m22 * g1 - m12 * g2) * inv
            wb = (m11 * g2 - m12 * g1) * inv
        else:
            status = 2
            wa = np.nan
            wb = np.nan
        W_out[t, 0] = wa
        W_out[t, 1] = wb
        code_out[t] = status
    ints[_COUNT] = count
    ints[_HEAD] = head
    ints[_SINCE] = since
    acc[0], acc[1], acc[2] = s1, s2, st
    acc[3], acc[4], acc[5], acc[6], acc[7] = s11, s12, s22, s1t, s2t
    acc[8], acc[9], acc[10] = h1, h2, ht
    return status, wa, wb


@njit(cache=True, error_model="numpy")
def wlsm2_chunk(
    u: FloatArray,
    ys: FloatArray,
    start: int,
    stop: int,
    paper: bool,
    gamma: float,
    W: FloatArray,
    P: FloatArray,
    W_out: FloatArray,
    code_out: CodeArray,
) -> tuple[int, float, float]:
    """First-order :func:`wlsm_chunk`: the same operations in the same order, unrolled.

    Returns the last row's ``(status, a, b)``.
    """
    w_a = W[0]
    w_b = W[1]
    p11 = P[0, 0]
    p12 = P[0, 1]
    p21 = P[1, 0]
    p22 = P[1, 1]
    # x - x is 0 for every finite x and NaN for inf or NaN: one test for all six.
    alive = (w_a - w_a) + (w_b - w_b) + (p11 - p11) + (p12 - p12) + (p21 - p21) + (p22 - p22) == 0.0
    alpha = 1.0 - gamma
    status = 0
    out_a = w_a
    out_b = w_b
    for t in range(start, stop):
        if not alive:
            status = 6
            out_a = np.nan
            out_b = np.nan
            code_out[t] = 6
            W_out[t, 0] = np.nan
            W_out[t, 1] = np.nan
            continue
        x1 = ys[t - 1]
        x2 = u[t - 1]
        if paper:
            v1 = (p11 / gamma) * x1 + (p12 / gamma) * x2
            v2 = (p21 / gamma) * x1 + (p22 / gamma) * x2
            denom = 1.0 / alpha + x1 * v1 + x2 * v2
        else:
            v1 = p11 * x1 + p12 * x2
            v2 = p12 * x1 + p22 * x2
            denom = gamma + x1 * v1 + x2 * v2
        k1 = v1 / denom
        k2 = v2 / denom
        err = ys[t] - x1 * w_a - x2 * w_b
        w_a = w_a + k1 * err
        w_b = w_b + k2 * err
        if paper:
            r1 = x1 * p11 + x2 * p21
            r2 = x1 * p12 + x2 * p22
            q11 = (p11 - k1 * r1) / gamma
            q12 = (p12 - k1 * r2) / gamma
            q21 = (p21 - k2 * r1) / gamma
            q22 = (p22 - k2 * r2) / gamma
        else:
            q11 = (p11 - k1 * v1) / gamma
            q12 = (p12 - k1 * v2) / gamma
            q21 = q12
            q22 = (p22 - k2 * v2) / gamma
        p11, p12, p21, p22 = q11, q12, q21, q22
        alive = (w_a - w_a) + (w_b - w_b) + (p11 - p11) + (p12 - p12) + (p21 - p21) + (
            p22 - p22
        ) == 0.0
        if alive:
            status = 0
            out_a = w_a
            out_b = w_b
        else:
            status = 6
            out_a = np.nan
            out_b = np.nan
        W_out[t, 0] = out_a
        W_out[t, 1] = out_b
        code_out[t] = status
    W[0] = w_a
    W[1] = w_b
    P[0, 0] = p11
    P[0, 1] = p12
    P[1, 0] = p21
    P[1, 1] = p22
    return status, out_a, out_b


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
