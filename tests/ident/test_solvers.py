"""The record solver (tall-skinny QR of ``[D | Y]``) is as accurate as the SVD of ``D``.

Both are compared with the exact least-squares solution of the same floating
point numbers, computed in rational arithmetic, on ill-conditioned records;
the normal equations are shown to lose what these keep, so the comparison can
fail.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from thermolab.ident import _regression as _reg
from thermolab.ident import least_squares
from thermolab.ident.models import ArxOrder
from thermolab.simulation import simulate_arx, simulate_first_order

EPS = float(np.finfo(np.float64).eps)


def exact_solution(D: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``argmin ||Y - D W||`` for the float data, in exact rational arithmetic."""
    rows = [[Fraction(float(v)) for v in row] for row in D]
    targets = [Fraction(float(v)) for v in Y]
    p = D.shape[1]
    G = [[sum((r[i] * r[j] for r in rows), Fraction(0)) for j in range(p)] for i in range(p)]
    h = [sum((r[i] * t for r, t in zip(rows, targets, strict=True)), Fraction(0)) for i in range(p)]
    # Gauss-Jordan elimination, exact.
    A = [G[i] + [h[i]] for i in range(p)]
    for col in range(p):
        pivot = next(r for r in range(col, p) if A[r][col] != 0)
        A[col], A[pivot] = A[pivot], A[col]
        for r in range(p):
            if r != col and A[r][col] != 0:
                f = A[r][col] / A[col][col]
                A[r] = [a - f * b for a, b in zip(A[r], A[col], strict=True)]
    return np.array([float(A[i][p] / A[i][i]) for i in range(p)])


def _slow_plant() -> tuple[np.ndarray, np.ndarray, ArxOrder, str]:
    # tau = 10^5 s sampled at 1 s: a = 1 - 1e-5, the y column nearly the constant one.
    rng = np.random.default_rng(1)
    u = np.r_[np.zeros(100), np.full(1400, 5.0)]
    y = simulate_first_order(u, 0.8, 1e5, 1.0, ambient=20.0) + rng.normal(0, 1e-7, u.size)
    return u, y, ArxOrder(1, 1, 0), "fit"


def _large_offset() -> tuple[np.ndarray, np.ndarray, ArxOrder, str]:
    # 1000 V of ambient under a 1 mV response: every column but the input is nearly constant.
    rng = np.random.default_rng(2)
    u = np.where((np.arange(1500) // 40) % 2 == 0, 1.0, 0.0)
    y = 1000.0 + simulate_first_order(u, 1e-3, 30.0, 1.0) + rng.normal(0, 1e-9, u.size)
    return u, y, ArxOrder(1, 1, 0), "fit"


def _oversampled_second_order() -> tuple[np.ndarray, np.ndarray, ArxOrder, str]:
    # Poles 0.999 and 0.998: the two output lags are nearly the same column.
    rng = np.random.default_rng(3)
    u = np.where((np.arange(1500) // 200) % 2 == 0, 6.0, 4.0)
    a = (0.999 + 0.998, -0.999 * 0.998)
    y = simulate_arx(u, a, (1e-5, 0.5e-5)) + rng.normal(0, 1e-8, u.size)
    return u, y, ArxOrder(2, 2, 0), "initial"


CASES = {
    "slow plant": _slow_plant,
    "large offset": _large_offset,
    "oversampled second order": _oversampled_second_order,
}


def _rel_err(W: np.ndarray, exact: np.ndarray) -> float:
    return float(np.linalg.norm(W - exact) / np.linalg.norm(exact))


@pytest.mark.parametrize("name", list(CASES))
def test_record_solver_is_as_accurate_as_svd(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    u, y, order, offset = CASES[name]()
    reg = _reg.build(u, y, order, offset)
    exact = exact_solution(reg.D, reg.Y)
    svd = _reg.solve(reg.D, reg.Y)
    # Small chunks: the factor is folded over dozens of chunks, as on a long record.
    monkeypatch.setattr(_reg, "CHUNK_ROWS", 64)
    qr = _reg.solve_record(u, y, order, offset)
    assert qr.ok
    assert svd.ok
    kappa = float(qr.s[0] / qr.s[-1])  # condition number of the equilibrated D
    assert kappa > 1e3, "the case must be ill-conditioned to test anything"
    np.testing.assert_allclose(qr.s, svd.s, rtol=1e-9)
    err_qr, err_svd = _rel_err(qr.W, exact), _rel_err(svd.W, exact)
    # Both lose about cond(D) digits, not cond(D)^2 ...
    assert err_qr <= 100 * kappa * EPS
    assert err_qr <= 10 * max(err_svd, kappa * EPS)
    # ... which the normal equations would: the comparison can fail.
    G = reg.D.T @ reg.D
    gram = np.linalg.solve(G, reg.D.T @ reg.Y)
    assert _rel_err(gram, exact) > 20 * err_qr
    # The residual sum of squares from the factor agrees with the residuals.
    res = reg.Y - reg.D @ qr.W
    assert qr.rss == pytest.approx(float(res @ res), rel=1e-6)


@pytest.mark.filterwarnings("ignore::thermolab.ident.IdentificationWarning")
def test_record_solver_keeps_least_squares_figures(monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunked or not, the same record gives the same model to 12 digits."""
    rng = np.random.default_rng(4)
    u = np.where((np.arange(30_000) // 300) % 2 == 0, 6.0, 4.0)
    y = simulate_first_order(u, 0.14, 250.0, 1.0) + rng.normal(0, 5e-3, u.size)
    whole = least_squares(u, y, 1.0, order=ArxOrder(), offset="fit", holdout=0.0)
    monkeypatch.setattr(_reg, "CHUNK_ROWS", 1000)
    chunked = least_squares(u, y, 1.0, order=ArxOrder(), offset="fit", holdout=0.0)
    reg = _reg.build(u, y, ArxOrder(), "fit")
    svd = _reg.solve(reg.D, reg.Y)
    for r in (whole, chunked):
        np.testing.assert_allclose(r.W, svd.W, rtol=1e-11)
        np.testing.assert_allclose(r.y_one_step, reg.D @ svd.W, rtol=1e-12)
    np.testing.assert_allclose([whole.K, whole.tau], [chunked.K, chunked.tau], rtol=1e-12)


def test_rank_deficiency_is_found_in_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_reg, "CHUNK_ROWS", 50)
    u = np.full(1000, 5.0)  # the input column is the constant column
    y = simulate_first_order(np.r_[0.0, u[1:]], 0.5, 40.0, 1.0)
    assert not _reg.solve_record(u, y, ArxOrder(), "fit").ok
    assert _reg.solve_record(u, y, ArxOrder(), "initial").ok
    assert not _reg.solve_record(np.zeros(1000), y, ArxOrder(), "initial").ok
