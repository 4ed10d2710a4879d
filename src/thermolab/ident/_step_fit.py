"""Step response method, fitting: the exponential tail and the level crossings.

The helpers of :func:`thermolab.ident.step.step_response` that estimate the
settled change and the crossing times (:mod:`thermolab.ident._step_detect`
finds the step).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

# SciPy is imported inside the functions that use it: at import, scipy.signal and
# scipy.optimize cost every lab, rig host and command 0.8 s of start-up.

__all__ = ["LEVEL_28", "LEVEL_63", "MIN_TAIL", "crossing_time", "fit_exponential_tail"]

FloatArray = npt.NDArray[np.float64]

#: The 63.2 % level of the method, exactly ``1 - 1/e``: an exponential reaches it at t = tau.
LEVEL_63 = -math.expm1(-1.0)
#: The 28.3 % level, ``1 - exp(-1/3)``: a first-order lag plus dead time reaches it
#: at ``theta + tau/3`` (and 63.2 % at ``theta + tau``), so the two give both.
LEVEL_28 = -math.expm1(-1.0 / 3.0)
# Input changes smaller than this fraction of the largest one are noise, not another step.
MIN_TAIL = 6
# Tail samples the search for the time constant looks at (the final polish uses all).
_SEARCH_POINTS = 4096
# Tail samples the final fit uses at most, evenly spread (plenty to average noise).
_POLISH_POINTS = 50_000


def fit_exponential_tail(tr: FloatArray, yr: FloatArray, span: float) -> tuple[float, float] | None:
    """Fit ``d - c exp(-(t - t0)/tau)``; return ``(d, tau)`` or None if it cannot be done.

    None as well when the arithmetic overflows (a record of huge values, or a
    few samples that let the polish run ``tau`` out of range): the caller then
    falls back to the last sample, never to an exception.
    """
    if tr.size < MIN_TAIL:
        return None
    with np.errstate(all="ignore"):
        try:
            return _fit(tr, yr, span)
        except (ArithmeticError, ValueError):
            return None


def _fit(tr: FloatArray, yr: FloatArray, span: float) -> tuple[float, float] | None:
    x = tr - tr[0]
    width = float(x[-1])
    if width <= 0.0:
        return None
    step = float(np.min(np.diff(tr)))
    # tau far below a sample or far beyond the record is not determined by the data.
    lo, hi = math.log(step / 20.0), math.log(20.0 * max(span, width))

    # The search for tau looks at a few thousand samples of the tail and the final
    # fit at up to 50 000, so a long record costs little more than a short one.
    xs, ys = _spread(x, _SEARCH_POINTS), _spread(yr, _SEARCH_POINTS)

    def sse(log_tau: float) -> float:
        return _separable_fit(xs, ys, log_tau)[0]

    grid = np.linspace(lo, hi, 64)
    costs = np.array([sse(g) for g in grid])
    if not (math.isfinite(lo) and math.isfinite(hi) and np.isfinite(costs).all()):
        return None  # squares of huge values overflow: nothing to compare
    i = int(np.argmin(costs))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    from scipy.optimize import minimize_scalar

    best = minimize_scalar(sse, bounds=(a, b), method="bounded")
    log_tau = float(best.x) if best.fun <= costs[i] else float(grid[i])
    # Brent's tolerance is relative to log(tau); Levenberg-Marquardt on all three
    # parameters polishes the solution to rounding, which the 63.2 % crossing needs.
    xp, yp = _spread(x, _POLISH_POINTS), _spread(yr, _POLISH_POINTS)
    cost, d0, c0 = _separable_fit(xp, yp, log_tau)

    def residual(p: FloatArray) -> FloatArray:
        r: FloatArray = p[0] - p[1] * np.exp(-xp * math.exp(-p[2])) - yp
        return r

    def jacobian(p: FloatArray) -> FloatArray:
        rate = math.exp(-p[2])
        e = np.exp(-xp * rate)
        return np.column_stack([np.ones_like(xp), -e, -p[1] * e * xp * rate])

    d = d0
    try:
        from scipy.optimize import least_squares

        polished = least_squares(
            residual,
            np.array([d0, c0, log_tau]),
            jac=jacobian,
            method="lm",
            xtol=1e-15,
            ftol=1e-15,
            gtol=1e-15,
        )
    except (ArithmeticError, ValueError):
        # On a few samples Levenberg-Marquardt can step tau to exp(-710): the
        # bounded search's answer stands.
        pass
    else:
        if polished.success and 2.0 * polished.cost <= cost and lo <= polished.x[2] < hi:
            d, log_tau = float(polished.x[0]), float(polished.x[2])
    if not math.isfinite(d) or log_tau >= hi - 1e-9:
        return None
    return d, math.exp(log_tau)


def _spread(a: FloatArray, m: int) -> FloatArray:
    """At most ``m`` samples of ``a``, evenly spread, first and last included."""
    if a.size <= m:
        return a
    return a[np.linspace(0, a.size - 1, m).astype(np.intp)]


def _separable_fit(x: FloatArray, y: FloatArray, log_tau: float) -> tuple[float, float, float]:
    """Least squares of ``y ~ d - c exp(-x/tau)`` for a fixed tau: ``(sse, d, c)``."""
    e = np.exp(-x * math.exp(-log_tau))
    e_mean, y_mean = float(e.mean()), float(y.mean())
    ec, yc = e - e_mean, y - y_mean
    see = float(ec @ ec)
    sey = float(ec @ yc)
    syy = float(yc @ yc)
    if see <= 0.0:
        return syy, y_mean, 0.0
    slope = sey / see
    return max(syy - slope * sey, 0.0), y_mean - slope * e_mean, -slope


def crossing_time(
    tr: FloatArray, z: FloatArray, z_noise: float, level: float = LEVEL_63
) -> tuple[float | None, float]:
    """Time (from the step) where the normalised response ``z`` reaches ``level`` (1 - 1/e).

    ``log(1 - z)`` is linear in time for an exponential, so the crossing is where a
    straight line through ``log(1 - z)`` meets ``-1``. Noise-free, the line goes
    through the two samples around the crossing (exact). With noise ``z_noise``
    the response wanders across the level several times; the line is then
    fitted to every sample within three noise deviations of the level, which
    averages the noise out instead of taking the first (early) crossing.
    """
    side = z >= level
    changes = np.flatnonzero(side[1:] != side[:-1]) + 1
    if changes.size == 0:
        if side[0]:
            return float(tr[0]), float(tr[0])
        return None, math.nan
    first, last = int(changes[0]), int(changes[-1])
    band = min(3.0 * z_noise, 0.25)
    sel = np.abs(z - level) <= band
    sel[[first - 1, first, last - 1, last]] = True
    sel &= z < 1.0
    if np.count_nonzero(sel) > 2:
        slope, intercept = np.polyfit(tr[sel], np.log1p(-z[sel]), 1)
        if slope < 0.0:
            tc = float((math.log1p(-level) - intercept) / slope)
            if tr[first - 1] - 1e-9 <= tc <= tr[last] + 1e-9 or first == last:
                return tc, tc
    tc = 0.5 * (
        _interpolate_crossing(tr, z, first, level) + _interpolate_crossing(tr, z, last, level)
    )
    return tc, tc


def _interpolate_crossing(tr: FloatArray, z: FloatArray, j: int, level: float) -> float:
    """Crossing of ``level`` between samples j-1 and j, exact for an exponential."""
    r0, r1 = 1.0 - z[j - 1], 1.0 - z[j]
    target = 1.0 - level
    if r0 > 0.0 and r1 > 0.0 and r0 != r1:
        frac = math.log(r0 / target) / math.log(r0 / r1)
    else:
        frac = (level - z[j - 1]) / (z[j] - z[j - 1])
    return float(tr[j - 1] + frac * (tr[j] - tr[j - 1]))
