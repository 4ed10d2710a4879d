"""Validation of an identified model, like MATLAB's ``compare`` and ``resid``.

* **Fit %** (``compare``): ``100 (1 - ||y - ŷ|| / ||y - mean(y)||)`` (NRMSE) of
  the free-run simulation, on the whole record and on a held-out final part the
  model was not fitted to.
* **Residual tests** (``resid``): the autocorrelation of the residuals at lags
  ``1..max_lag`` (white if the model explains everything it can) and their
  cross-correlation with the input at lags ``0..max_lag`` (zero if no input
  effect is left), each against the 99 % confidence bound ``2.576 / sqrt(N)``
  of a white sequence. A test counts as failed when at least two lags (and 1 %
  of them) fall outside the bound, or one falls beyond 1.5 times it (3.9
  standard deviations: by chance in about 0.3 % of 25-lag tests), so that one
  stray lag does not condemn a good model (alone it would in 22 % of them).
* **Physical sense**: a time constant under two sample periods or far beyond
  the record, a gain of the wrong sign.
* **Timing**: a time axis whose spread would bias methods that assume a fixed
  sample period.

Failed tests come with the likely cause (dead time, higher order, offset,
noise) in words. Hand-written: scipy and statsmodels have the correlations but
not this reading of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError
from thermolab.jsonsafe import finite_or_none

from . import _validation as _v
from ._lagged import shifted_dots
from .notes import note

__all__ = [
    "CONFIDENCE_Z99",
    "ResidualTest",
    "fit_percent",
    "plausibility_warnings",
    "residual_test",
    "timing_warnings",
    "timing_warnings_from_steps",
]

FloatArray = npt.NDArray[np.float64]

#: Two-sided 99 % point of the standard normal: the bound is ``z / sqrt(N)``.
CONFIDENCE_Z99 = 2.5758293035489004
# Time steps deviating from the median by more than this fraction bias fixed-dt methods.
_JITTER_LIMIT = 0.05
# A gap: a step this many times the median step.
_GAP_FACTOR = 1.5
# Residuals below this fraction of the output scale are rounding: the fit is exact.
_EXACT = 1e-9


def fit_percent(y: npt.ArrayLike, yhat: npt.ArrayLike) -> float:
    """NRMSE fit in percent: 100 is perfect, 0 no better than the mean.

    Returns NaN when ``y`` is constant and ``-inf`` when ``yhat`` is not finite.

    Examples
    --------
    >>> fit_percent([0.0, 1.0, 2.0], [0.0, 1.0, 2.0])
    100.0
    >>> fit_percent([0.0, 1.0, 2.0], [1.0, 1.0, 1.0])
    0.0
    """
    ya = np.asarray(y, dtype=np.float64)
    yh = np.asarray(yhat, dtype=np.float64)
    with np.errstate(all="ignore"):
        spread = float(np.linalg.norm(ya - ya.mean()))
        if spread == 0.0:
            return math.nan
        err = float(np.linalg.norm(ya - yh))
    if not math.isfinite(err):
        return -math.inf
    return 100.0 * (1.0 - err / spread)


@dataclass(frozen=True)
class ResidualTest:
    """Whiteness of the residuals and their independence from the input (``resid``).

    Attributes
    ----------
    autocorrelation : numpy.ndarray
        Normalised autocorrelation of the residuals at lags ``1 .. max_lag``.
    cross_correlation : numpy.ndarray
        Normalised correlation of ``u[k - lag]`` with ``e[k]`` at lags ``0 .. max_lag``.
    bound : float
        The 99 % confidence bound, ``2.576 / sqrt(N)``.
    white : bool
        The autocorrelation stays within the bound (see the module notes).
    independent : bool
        The cross-correlation stays within the bound.
    exact : bool
        The residuals are rounding errors (an exact fit): both tests pass.
    """

    autocorrelation: FloatArray
    cross_correlation: FloatArray
    bound: float
    white: bool
    independent: bool
    exact: bool = False

    @property
    def passed(self) -> bool:
        """Both tests passed."""
        return self.white and self.independent

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: the correlations, the bound and the verdicts."""
        return {
            "autocorrelation": [finite_or_none(x) for x in self.autocorrelation.tolist()],
            "cross_correlation": [finite_or_none(x) for x in self.cross_correlation.tolist()],
            "bound": self.bound,
            "confidence": 0.99,
            "white": self.white,
            "independent": self.independent,
            "exact": self.exact,
            "passed": self.passed,
        }


def _outside(r: FloatArray, bound: float) -> bool:
    count = int(np.count_nonzero(np.abs(r) > bound))
    return count >= max(2, math.ceil(0.01 * r.size)) or bool(np.any(np.abs(r) > 1.5 * bound))


def residual_test(
    residuals: npt.ArrayLike, u: npt.ArrayLike, *, max_lag: int = 25, scale: float = 1.0
) -> ResidualTest:
    """Test residuals for whiteness and for independence from the input.

    Parameters
    ----------
    residuals : array_like
        Model residuals ``e[k]``.
    u : array_like
        The input aligned with ``residuals`` (``u[k]`` beside ``e[k]``).
    max_lag : int, optional
        Largest lag tested (default 25, MATLAB's ``resid``).
    scale : float, optional
        Size of the output (volts); residuals under ``1e-9 * scale`` count as an
        exact fit.

    Returns
    -------
    ResidualTest

    Raises
    ------
    InvalidDataError
        If the arrays are not finite or differ in length.
    InvalidParameterError
        If ``max_lag`` is not an integer >= 1 or leaves fewer than 10 samples.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> e = rng.normal(size=2000)
    >>> residual_test(e, rng.normal(size=2000)).passed
    True
    >>> residual_test(np.convolve(e, np.ones(5), "same"), rng.normal(size=2000)).white
    False
    """
    e, ua = _v.as_record(u, residuals)
    e, ua = ua, e  # as_record names its arguments u, y
    lag = _v.integer("max_lag", max_lag, 1, "at least one lag")
    n = e.size
    if n - lag < 10:
        raise InvalidParameterError(
            f"max_lag = {lag} leaves {n - lag} samples of {n}; use a smaller max_lag "
            "or a longer record"
        )
    bound = CONFIDENCE_Z99 / math.sqrt(n)
    ec = e - e.mean()
    uc = ua - ua.mean()
    ee = float(ec @ ec)
    uu = float(uc @ uc)
    if math.sqrt(ee / n) <= _EXACT * max(scale, 1e-300):
        zeros = np.zeros(lag)
        return ResidualTest(zeros, np.zeros(lag + 1), bound, True, True, exact=True)
    # auto[j - 1] = ec[j:] @ ec[:n - j], cross[j] = ec[j:] @ uc[:n - j], in one pass each.
    auto = shifted_dots(ec, ec, list(range(1, lag + 1))) / ee
    if uu > 0.0:
        cross = shifted_dots(uc, ec, list(range(lag + 1))) / math.sqrt(ee * uu)
    else:
        cross = np.zeros(lag + 1)
    return ResidualTest(auto, cross, bound, not _outside(auto, bound), not _outside(cross, bound))


def residual_advice(test: ResidualTest, delay_searched: bool) -> str | None:
    """The likely cause of failed residual tests, in words (None when they pass)."""
    if test.passed:
        return None
    if not test.independent:
        early = np.abs(test.cross_correlation[: min(4, test.cross_correlation.size)])
        short_lags = bool((early > test.bound).any()) and not delay_searched
        code = "residual_dead_time" if short_lags else "residual_higher_order"
        return note(code, bound=test.bound)
    return note("residual_not_white", bound=test.bound)


def plausibility_warnings(
    K: float,
    tau: float,
    dt: float,
    duration: float,
    *,
    expected_sign: int | None = None,
) -> list[str]:
    """Warnings for estimates outside physical sense.

    Parameters
    ----------
    K, tau : float
        Gain and time constant (seconds); NaN gives no warning (the model's own
        ``reason`` covers it).
    dt : float
        Sample period in seconds.
    duration : float
        Record length in seconds.
    expected_sign : {1, -1} or None, optional
        The sign the gain must have (+1 for a heater read by a temperature
        sensor); None skips the check.

    Returns
    -------
    list of str

    Raises
    ------
    InvalidParameterError
        If ``expected_sign`` is not 1, -1 or None.

    Examples
    --------
    >>> plausibility_warnings(0.14, 0.33, 1.0, 600.0)[0].split(":")[0]
    'implausible time constant'
    >>> plausibility_warnings(-0.14, 250.0, 1.0, 2000.0, expected_sign=1)[0].split(":")[0]
    'implausible gain'
    """
    if expected_sign not in (None, 1, -1):
        raise InvalidParameterError(
            f"expected_sign must be 1 (output rises with input), -1 or None, got {expected_sign!r}"
        )
    out: list[str] = []
    if math.isfinite(tau):
        if tau < 2.0 * dt:
            out.append(note("tau_under_two_periods", tau=tau, dt=dt))
        elif tau > 10.0 * duration:
            out.append(note("tau_over_ten_records", tau=tau, duration=duration))
    if expected_sign is not None and math.isfinite(K) and K * expected_sign <= 0.0:
        out.append(note("gain_not_positive" if expected_sign > 0 else "gain_not_negative", K=K))
    return out


def timing_warnings(t: npt.ArrayLike) -> list[str]:
    """Warnings about an irregular time axis (jitter, gaps).

    Parameters
    ----------
    t : array_like
        Sample times in seconds, strictly increasing.

    Returns
    -------
    list of str
        A warning when the sample steps spread more than 5 % around the median
        (methods that assume a fixed ``dt`` are then biased) and one naming the
        gaps (steps over 1.5 median periods).

    Examples
    --------
    >>> import numpy as np
    >>> timing_warnings(np.arange(100.0))
    []
    >>> t = np.arange(100.0); t[50:] += 60.0
    >>> [w.split(":")[0] for w in timing_warnings(t)]
    ['gap in time']
    """
    ta, steps = _v.check_time_steps(t)
    return timing_warnings_from_steps(ta, steps)


def timing_warnings_from_steps(ta: FloatArray, steps: FloatArray) -> list[str]:
    """:func:`timing_warnings` of a checked time axis and its steps (``diff(ta)``)."""
    if ta.size < 3:
        return []
    med = float(np.median(steps))
    out: list[str] = []
    gaps = np.flatnonzero(steps > _GAP_FACTOR * med)
    regular = np.delete(steps, gaps) if gaps.size else steps
    spread = float(np.std(regular) / med) if regular.size else 0.0
    if spread > _JITTER_LIMIT:
        limit = 100 * _JITTER_LIMIT
        out.append(note("timing_jitter", spread=100 * spread, median=med, limit=limit))
    if gaps.size:
        missing = int(np.round(steps[gaps] / med).sum() - gaps.size)
        first = float(ta[gaps[0]])
        out.append(note("time_gaps", count=gaps.size, first=first, missing=missing))
    return out
