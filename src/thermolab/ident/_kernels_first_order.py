"""Numba-compiled kernels of MALSM and WLSM for first order, the paper's case.

First order (eq. 4, W = [a, b], no constant term): the same algorithms with the
2x2 algebra written out and the state held in local variables for the length
of a chunk, which is what the runner and the paper's tables use. (Held in
arrays between samples, the state's loads and stores would be serialised by
possible aliasing and cost ten times the arithmetic.)

The algorithms, status codes and state layouts are those of the general kernels
(:mod:`thermolab.ident._kernels`); the tests check that both give the same
estimates.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import _COUNT, _EVERY, _HEAD, _SINCE, RCOND_MIN, CodeArray, FloatArray, IntArray

__all__ = ["malsm2_chunk", "wlsm2_chunk"]


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
