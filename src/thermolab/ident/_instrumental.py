"""The ambient of a first order with a constant term, by instrumental variables.

Least squares on ``y[k+1] = a y[k] + b u[k-d] + c`` is biased when ``y`` is
measured with noise (the regressor ``y[k]`` carries the noise the target is
compared against): ``a`` comes out low, and the free constant ``c`` absorbs
the difference, so a record that starts at rest at ambient looks better
predicted *with* a constant term whose ambient is far from ``y[0]``. On a slow
plant under a square wave the operating-point decision then picked ``"fit"``
and ``K`` came out three times low.

Replacing ``y[k]`` in the instruments by the noise-free simulated output of a
preliminary model (the classic IV estimator, Söderström & Stoica, *System
Identification*, ch. 8) removes that bias: the instruments are correlated
with the regressors and not with the noise. The operating-point decision uses
the resulting ambient, and its standard error, to test "the record starts at
rest at ``y[0]``" against "it starts settled under ``u[0]``".
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

# SciPy is imported inside the functions that use it: at import, scipy.signal and
# scipy.optimize cost every lab, rig host and command 0.8 s of start-up.
from . import _regression as _reg
from .deadtime import SEARCH_SAMPLES
from .models import ArxOrder

__all__ = ["InstrumentalAmbient", "instrumental_ambient"]

FloatArray = npt.NDArray[np.float64]

#: Refinements of the instruments (each simulates with the previous estimate).
_PASSES = 2


class InstrumentalAmbient(NamedTuple):
    """The IV estimate of a first order with a constant term."""

    ambient: float  # c / (1 - a): the output at rest with the input off
    stderr: float  # its standard error (delta method)
    gain: float  # b / (1 - a)


def instrumental_ambient(u: FloatArray, y: FloatArray, delay: int) -> InstrumentalAmbient | None:
    """Ambient, its standard error and the gain of ``y[k+1] = a y[k] + b u[k-d] + c``.

    Uses the first :data:`~thermolab.ident.deadtime.SEARCH_SAMPLES` samples
    (the delay search's rows). ``None`` when the estimate has no first-order
    meaning (singular equations, or ``a`` outside (0, 1)).
    """
    n = min(u.size, SEARCH_SAMPLES)
    if n < delay + 8:
        return None
    u, y = u[:n], y[:n]
    sol = _reg.solve_record(u, y, ArxOrder(1, 1, delay), "fit")
    if not sol.ok:
        return None
    a, b, c = (float(w) for w in sol.W)
    rows = np.arange(delay, n - 1)
    phi = np.column_stack([y[rows], u[rows - delay], np.ones(rows.size)])
    target = y[rows + 1]
    # Input before the record: held at u[0], as the simulation of a record does.
    drive_u = np.r_[np.full(delay, u[0]), u[: n - delay]]
    powers = np.arange(1, n, dtype=np.float64)
    for _ in range(_PASSES):
        if not 0.0 < a < 1.0:
            return None
        from scipy.signal import lfilter

        free = lfilter([1.0], [1.0, -a], b * drive_u + c)
        x = np.empty(n)
        x[0] = y[0]
        x[1:] = free[:-1] + np.power(a, powers) * y[0]
        z = np.column_stack([x[rows], u[rows - delay], np.ones(rows.size)])
        moment = z.T @ phi
        try:
            theta = np.linalg.solve(moment, z.T @ target)
        except np.linalg.LinAlgError:
            return None
        a, b, c = (float(w) for w in theta)
    if not (0.0 < a < 1.0 and np.isfinite(theta).all()):
        return None
    resid = target - phi @ theta
    sigma2 = float(resid @ resid) / max(rows.size - 3, 1)
    inv = np.linalg.inv(moment)
    cov = sigma2 * inv @ (z.T @ z) @ inv.T
    den = 1.0 - a
    grad = np.array([c / den**2, 0.0, 1.0 / den])
    stderr = math.sqrt(max(float(grad @ cov @ grad), 0.0))
    return InstrumentalAmbient(c / den, stderr, b / den)
