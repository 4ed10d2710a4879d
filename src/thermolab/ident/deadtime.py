"""Dead time of a record: the delay of a first-order ARX model chosen from the data.

A first-order model fitted with no delay to a plant with dead time (the TCLab
kit has 15–17 s) is badly wrong (+28 % in K, +116 % in tau). The least-squares
methods therefore try every delay ``d = 0 .. max_delay`` samples of the model
``y[k+1] = a y[k] + b u[k-d] (+ c)`` on the same rows and keep the shortest
delay whose one-step prediction error is within the Bayesian information
criterion's margin of the least (a longer delay must earn its place as one more
parameter would). This is the loss MATLAB's ``delayest`` compares. The free-run
simulation error was tried as the criterion too and rejected: with
measurement noise the biased ARX estimates let a wrong delay simulate a
square-wave record better (a delay one or two input periods long), while the
one-step error found the right delay on every record tried (steps and square
waves, 0 and 15–17 s of dead time, 5 mV to 0.1 V of noise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

from thermolab.errors import InvalidParameterError
from thermolab.jsonsafe import finite_or_none

from . import _regression as _reg
from ._lagged import shifted_dots

__all__ = [
    "DEFAULT_MAX_DELAY",
    "SEARCH_SAMPLES",
    "DelaySearch",
    "default_max_delay",
    "search_delay",
]

FloatArray = npt.NDArray[np.float64]

#: Longest dead time tried by default, in samples (the TCLab kit's 15–17 s at
#: T = 1 s with room to spare); never more than a tenth of the record.
DEFAULT_MAX_DELAY = 60

#: Samples the delay search looks at (the start of the record, where the first
#: steps are), so that a 10⁷-sample record costs no more than a long experiment.
SEARCH_SAMPLES = 100_000


_CRITERIA = {
    "one-step": "least one-step prediction error over delays 0..max_delay; the shortest "
    "delay within the BIC margin (1 + log(m)/m) of the best",
    "simulation": "least free-run simulation error over delays 0..max_delay; the shortest "
    "delay within the BIC margin (1 + log(m)/m) of the best",
}


def _smallest_near_best(sse: FloatArray, m: int, rounding: float) -> int:
    """The shortest delay whose error is within the BIC margin of the least.

    A longer delay must lower ``m log(SSE)`` by more than ``log(m)`` (what one
    more parameter costs in the Bayesian information criterion) to be kept:
    noise alone then rarely buys a delay the plant does not have, and a
    periodic input's aliases (a delay one period longer fits as well) lose.
    Errors under ``rounding`` are ties (an exact fit at several delays: a
    single step lets a long delay pass the response off as the record's start).
    """
    finite = np.isfinite(sse)
    if not finite.any():
        return 0
    least = float(sse[finite].min())
    margin = max(least * (1.0 + math.log(max(m, 2)) / max(m, 1)), rounding)
    return int(np.flatnonzero(finite & (sse <= margin))[0])


def default_max_delay(n_samples: int) -> int:
    """``min(DEFAULT_MAX_DELAY, n_samples // 10)``: the delays tried by default.

    Examples
    --------
    >>> default_max_delay(2000), default_max_delay(100)
    (60, 10)
    """
    return max(0, min(DEFAULT_MAX_DELAY, n_samples // 10))


@dataclass(frozen=True)
class DelaySearch:
    """The delays tried and the criterion of each.

    Attributes
    ----------
    delay : int
        The chosen delay in samples beyond the natural one (see :class:`ArxOrder`).
    delays : tuple of int
        The delays tried, ``0 .. max_delay``.
    sse : tuple of float
        Sum of squared free-run simulation errors of each, over the same rows
        (inf where the candidate could not be fitted or diverged).
    criterion : str
        The rule, in words.
    """

    delay: int
    delays: tuple[int, ...]
    sse: tuple[float, ...]
    criterion: str = ""

    def to_dict(self) -> dict[str, Any]:
        """``{"delay", "max_delay", "criterion", "sse"}`` (JSON-safe)."""
        return {
            "delay": self.delay,
            "max_delay": self.delays[-1] if self.delays else 0,
            "criterion": self.criterion,
            "sse": [finite_or_none(x) for x in self.sse],
        }


def search_delay(
    u: FloatArray,
    y: FloatArray,
    offset: str | float,
    max_delay: int,
    criterion: str = "one-step",
) -> DelaySearch:
    """Fit ``y[k+1] = a y[k] + b u[k-d] (+ c)`` for ``d = 0 .. max_delay``; keep the best.

    Parameters
    ----------
    u, y : numpy.ndarray
        Checked input and output records.
    offset : {"initial", "fit", "none"} or float
        The operating-point handling of every candidate.
    max_delay : int
        Largest delay tried, in samples (>= 0).
    criterion : {"one-step", "simulation"}, optional
        The error compared: one-step prediction (default) or free-run simulation.

    Returns
    -------
    DelaySearch
        The chosen delay and the criterion of every candidate.

    Notes
    -----
    Every candidate regresses the same rows ``y[1] .. y[n-1]``: the input before
    the record is taken as 0 V (at rest) for a record without a constant term and
    as held at ``u[0]`` (settled) with one, so a long delay does not cost the
    rows that hold the step. Each
    candidate is solved from its 2×2 or 3×3 normal equations (four dot products
    of the record), which is accurate enough to rank them; the chosen one is
    then solved properly by the caller. Only the first :data:`SEARCH_SAMPLES`
    samples are searched.

    Examples
    --------
    >>> import numpy as np
    >>> a, b = 0.95, 0.05
    >>> u = np.r_[np.zeros(20), np.ones(200)]
    >>> y = np.zeros(220)
    >>> for k in range(219):
    ...     y[k + 1] = a * y[k] + b * u[k - 7] if k >= 7 else 0.0
    >>> search_delay(u, y, "initial", 15).delay
    7
    """
    if criterion not in _CRITERIA:
        raise InvalidParameterError(
            f"criterion must be one of {', '.join(map(repr, _CRITERIA))}, got {criterion!r}"
        )
    u = u[:SEARCH_SAMPLES]
    y = y[:SEARCH_SAMPLES]
    delays = tuple(range(max_delay + 1))
    y_shift, constant = _reg.offset_shift(offset, float(y[0]))
    ys = y - y_shift
    # Before the record the plant rested with the input off ("initial", a known
    # ambient, the paper's raw form) or sat under the first input ("fit").
    pad = float(u[0]) if constant else 0.0
    held = np.concatenate([np.full(max_delay, pad), u])
    m = y.size - 1
    held = held[: max_delay + m]
    prev, Y = ys[:-1], ys[1:]
    nd = max_delay + 1
    d = np.arange(nd)
    start = max_delay - d  # the input column of delay d is held[start : start + m]
    # Every delay's normal equations at once: sliding sums and correlations.
    cs = np.concatenate([[0.0], np.cumsum(held)])
    cs2 = np.concatenate([[0.0], np.cumsum(held * held)])
    u1 = cs[start + m] - cs[start]
    uu = cs2[start + m] - cs2[start]
    # pu[d] = held[start[d] : start[d] + m] @ prev (np.correlate's direct loop
    # took 0.25 s per call here).
    pu = shifted_dots(prev, held, start.tolist())
    uY = shifted_dots(Y, held, start.tolist())
    pp, pY = float(prev @ prev), float(prev @ Y)
    G = np.empty((nd, 4 if constant else 2, 4 if constant else 2))
    G[:, 0, 0], G[:, 0, 1], G[:, 1, 1] = pp, pu, uu
    rhs = np.empty((nd, G.shape[1]))
    rhs[:, 0], rhs[:, 1] = pY, uY
    if constant:
        # The rows before the delayed input enters (k < d) see the input from
        # before the record, unknown for a moving start: a column that is 1 on
        # those rows absorbs b (u_before - u[0]) exactly.
        cp = np.concatenate([[0.0], np.cumsum(prev)])
        cY = np.concatenate([[0.0], np.cumsum(Y)])
        G[:, 0, 2], G[:, 1, 2], G[:, 2, 2] = cp[-1], u1, float(m)
        G[:, 0, 3], G[:, 1, 3], G[:, 2, 3], G[:, 3, 3] = cp[d], pad * d, d, d
        rhs[:, 2], rhs[:, 3] = cY[-1], cY[d]
    upper = np.triu_indices(G.shape[1], 1)
    G[:, upper[1], upper[0]] = G[:, upper[0], upper[1]]
    # Equilibrate, then a pseudo-inverse: the pre-record column is empty at d = 0.
    diag = np.sqrt(np.einsum("kii->ki", G))
    scale_cols = np.where(diag > 0.0, 1.0 / np.where(diag > 0.0, diag, 1.0), 0.0)
    Gs = G * scale_cols[:, :, None] * scale_cols[:, None, :]
    W = (np.linalg.pinv(Gs, rcond=1e-13) @ (rhs * scale_cols)[..., None])[..., 0] * scale_cols

    def exact(k: int) -> float:
        ud = held[start[k] : start[k] + m]
        if criterion == "simulation":
            drive = W[k, 1] * ud + (W[k, 2] if constant else 0.0)
            if constant:
                drive[: d[k]] += W[k, 3]
            with np.errstate(all="ignore"):
                out = lfilter([1.0], [1.0, -W[k, 0]], drive, zi=[W[k, 0] * ys[0]])[0]
                err = float(np.sum((Y - out) ** 2))
        else:
            res = Y - W[k, 0] * prev - W[k, 1] * ud
            if constant:
                res -= W[k, 2]
                res[: d[k]] -= W[k, 3]
            err = float(shifted_dots(res, res, [0])[0])
        return err if math.isfinite(err) else math.inf

    YY = float(Y @ Y)
    if criterion == "simulation":
        sse = [exact(k) for k in range(nd)]
    else:
        # One-step errors from the normal equations, YᵀY - Wᵀ rhs; that
        # difference cancels to about 1e-13 YᵀY, so the few candidates near the
        # least are recomputed from their residuals.
        quick = np.maximum(YY - np.einsum("ki,ki->k", W, rhs), 0.0)
        sse = quick.tolist()
        near = np.flatnonzero(quick <= 10.0 * float(quick.min()) + 1e-10 * YY)
        for k in near[:16].tolist() + np.argsort(quick)[:3].tolist():
            sse[k] = exact(int(k))
    scale = max(float(np.max(np.abs(ys))), 1e-300)
    best = _smallest_near_best(np.asarray(sse), Y.size, Y.size * (1e-9 * scale) ** 2)
    return DelaySearch(best, delays, tuple(sse), _CRITERIA[criterion])
