"""Dead time of a record: the delay of a first-order ARX model chosen from the data.

A first-order model fitted with no delay to a plant with dead time (the TCLab
kit has 15–17 s) is badly wrong (+28 % in K, +116 % in tau). The least-squares
methods therefore try every delay ``d = 0 .. max_delay`` samples of the model
``y[k+1] = a y[k] + b u[k-d] (+ c)`` and keep the one whose **free-run
simulation** reproduces the record best (least sum of squared simulation
errors over the rows every candidate can use). The simulation error is the
criterion rather than the one-step residual because a wrong delay shifts the
whole response, which a free run exposes, while a one-step predictor hides it
behind the measured previous output; every candidate has the same number of
parameters, so this is also the minimum of an information criterion (AIC/BIC)
over the delays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

from thermolab.jsonsafe import finite_or_none

from . import _regression as _reg
from .models import ArxOrder

__all__ = ["DEFAULT_MAX_DELAY", "DelaySearch", "default_max_delay", "search_delay"]

FloatArray = npt.NDArray[np.float64]

#: Longest dead time tried by default, in samples (the TCLab kit's 15–17 s at
#: T = 1 s with room to spare); never more than a tenth of the record.
DEFAULT_MAX_DELAY = 60


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
    criterion: str = "least free-run simulation error over delays 0..max_delay"

    def to_dict(self) -> dict[str, Any]:
        """``{"delay", "max_delay", "criterion", "sse"}`` (JSON-safe)."""
        return {
            "delay": self.delay,
            "max_delay": self.delays[-1] if self.delays else 0,
            "criterion": self.criterion,
            "sse": [finite_or_none(x) for x in self.sse],
        }


def search_delay(
    u: FloatArray, y: FloatArray, offset: str | float, max_delay: int
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

    Returns
    -------
    DelaySearch
        The chosen delay and the criterion of every candidate.

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
    delays = tuple(range(max_delay + 1))
    sse: list[float] = []
    for d in delays:
        order = ArxOrder(1, 1, d)
        reg = _reg.build(u, y, order, offset)
        skip = max_delay - d  # the rows every candidate has
        D, Y = reg.D[skip:], reg.Y[skip:]
        if Y.size <= D.shape[1]:
            sse.append(math.inf)
            continue
        W, *_ = np.linalg.lstsq(D, Y, rcond=None)
        start = float(y[max_delay] - reg.y_shift)
        drive = D[:, 1:] @ W[1:]
        with np.errstate(all="ignore"):
            sim = lfilter([1.0], [1.0, -W[0]], drive, zi=[W[0] * start])[0]
            err = float(np.sum((Y - sim) ** 2))
        sse.append(err if math.isfinite(err) else math.inf)
    best = int(np.argmin(sse))
    return DelaySearch(best, delays, tuple(sse))
