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
    held = np.concatenate([np.full(max_delay, u[0] if constant else 0.0), u])
    m = y.size - 1
    prev, Y = ys[:-1], ys[1:]
    pp, pY = float(prev @ prev), float(prev @ Y)
    p1, Y1 = float(prev.sum()), float(Y.sum())
    sse: list[float] = []
    for d in delays:
        ud = held[max_delay - d : max_delay - d + m]
        pu, uu, uY = float(prev @ ud), float(ud @ ud), float(ud @ Y)
        if constant:
            # The rows before the delayed input enters (k < d) see the input from
            # before the record, unknown for a moving start: a column that is 1 on
            # those rows absorbs b (u_before - u[0]) exactly.
            u1 = float(ud.sum())
            pre_p, pre_u, pre_Y = float(prev[:d].sum()), float(ud[:d].sum()), float(Y[:d].sum())
            G = np.array(
                [
                    [pp, pu, p1, pre_p],
                    [pu, uu, u1, pre_u],
                    [p1, u1, float(m), float(d)],
                    [pre_p, pre_u, float(d), float(d)],
                ]
            )
            rhs = np.array([pY, uY, Y1, pre_Y])
        else:
            G = np.array([[pp, pu], [pu, uu]])
            rhs = np.array([pY, uY])
        W, *_ = np.linalg.lstsq(G, rhs, rcond=None)
        if criterion == "simulation":
            drive = W[1] * ud + (W[2] if constant else 0.0)
            if constant:
                drive[:d] += W[3]
            with np.errstate(all="ignore"):
                sim = lfilter([1.0], [1.0, -W[0]], drive, zi=[W[0] * ys[0]])[0]
                err = float(np.sum((Y - sim) ** 2))
        else:
            res = Y - W[0] * prev - W[1] * ud
            if constant:
                res = res - W[2]
                res[:d] -= W[3]
            err = float(res @ res)
        sse.append(err if math.isfinite(err) else math.inf)
    scale = max(float(np.max(np.abs(ys))), 1e-300)
    best = _smallest_near_best(np.asarray(sse), Y.size, Y.size * (1e-9 * scale) ** 2)
    return DelaySearch(best, delays, tuple(sse), _CRITERIA[criterion])
