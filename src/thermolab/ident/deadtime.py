"""Dead time of a record: the delay of a first-order ARX model chosen from the data.

A first-order model fitted with no delay to a plant with dead time (the TCLab
kit has 15–17 s) is badly wrong (+28 % in K, +116 % in tau). The least-squares
methods therefore try every delay ``d = 0 .. max_delay`` samples of the model
``y[k+1] = a y[k] + b u[k-d] (+ c)`` on the same rows and keep the shortest
delay whose error is within the Bayesian information criterion's margin of the
least (a longer delay must earn its place as one more parameter would).

Two errors can be compared. The one-step prediction error (the loss MATLAB's
``delayest`` compares) finds the ARX delay: on a plant that is exactly first
order plus dead time it is the dead time, but on a real kit, whose sensor adds
a lag of its own, it is the first visible response (12 s on the TCLab twin,
whose first order plus dead time equivalent has θ 15.9 s). The free-run
simulation error finds the delay of the first-order model that best
reproduces the record, which is that FOPDT-equivalent θ (15–16 s on the twin):
it is the default of the least-squares methods (``"simulation"``). Compared
over every delay, with measurement noise it let a wrong delay simulate a
square wave better (the ARX estimates' noise bias), so it is compared only
from the one-step delay ``d1`` (the first visible response) to ``2·d1`` (a
sensor lag shorter than the transport delay, as on the kits it is for). A
delay one input half-period long once fitted a square wave with a negative
gain (the input's repeat passed off as the response): every search stops
short of the input's repeat (:func:`input_repeat`), and when two separate
delays still fit equally well it says so (:attr:`DelaySearch.warning`). The operating-point decision
keeps the one-step error, whose BIC it compares.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

# SciPy is imported inside the functions that use it: at import, scipy.signal and
# scipy.optimize cost every lab, rig host and command 0.8 s of start-up.
from thermolab.errors import InvalidParameterError
from thermolab.jsonsafe import finite_or_none

from . import _regression as _reg
from ._lagged import shifted_dots
from .notes import note

__all__ = [
    "DEFAULT_CRITERION",
    "DEFAULT_MAX_DELAY",
    "SEARCH_SAMPLES",
    "DelaySearch",
    "default_max_delay",
    "input_repeat",
    "search_delay",
]

FloatArray = npt.NDArray[np.float64]

#: Longest dead time tried by default, in samples (the TCLab kit's 15–17 s at
#: T = 1 s with room to spare); never more than a tenth of the record.
DEFAULT_MAX_DELAY = 60

#: Samples the delay search looks at (the start of the record, where the first
#: steps are), so that a 10⁷-sample record costs no more than a long experiment.
SEARCH_SAMPLES = 100_000


#: The error the least-squares methods' dead time minimises by default.
DEFAULT_CRITERION = "simulation"

_CRITERIA = {
    "one-step": "least one-step prediction error over delays 0..max_delay; the shortest "
    "delay within the BIC margin (1 + log(m)/m) of the best",
    "simulation": "least free-run simulation error over delays d1..2*d1, d1 the one-step "
    "delay (the first visible response); the shortest delay within the BIC margin "
    "(1 + log(m)/m) of the best; delays are tried below the input's repeat",
}


def _smallest_near_best(sse: FloatArray, m: int, rounding: float) -> tuple[int, float]:
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
        return 0, math.inf
    least = float(sse[finite].min())
    margin = max(least * (1.0 + math.log(max(m, 2)) / max(m, 1)), rounding)
    return int(np.flatnonzero(finite & (sse <= margin))[0]), margin


def default_max_delay(n_samples: int) -> int:
    """``min(DEFAULT_MAX_DELAY, n_samples // 10)``: the delays tried by default.

    Examples
    --------
    >>> default_max_delay(2000), default_max_delay(100)
    (60, 10)
    """
    return max(0, min(DEFAULT_MAX_DELAY, n_samples // 10))


#: An input whose autocorrelation, after falling below :data:`_DECORRELATED`,
#: comes back to this size (either sign) repeats: a delay that long cannot be
#: told from the input's own repeat.
_REPEATS = 0.9
_DECORRELATED = 0.5


def input_repeat(u: FloatArray, longest: int) -> tuple[int, int] | None:
    """Where the input repeats itself within ``1 .. longest`` lags, or None.

    A lag repeats when the input's autocorrelation (mean removed), having
    fallen below 0.5, is back to 0.9 in size: a square wave of period ``P``
    repeats, sign flipped, at ``P/2``. A step or random steps never do. The
    delays told apart from the repeat are those before the autocorrelation
    first crosses zero (``P/4``): beyond, a delay shifted by the repeat fits
    about as well as the true one when the noise hides the small ripple.

    Returns
    -------
    tuple of int or None
        ``(repeat, longest delay told apart)``.

    Examples
    --------
    >>> import numpy as np
    >>> square = np.where((np.arange(2000) // 50) % 2 == 0, 6.0, 4.0)
    >>> input_repeat(square, 60), input_repeat(np.r_[np.zeros(20), np.ones(500)], 60)
    ((49, 25), None)
    """
    x = u[:SEARCH_SAMPLES] - float(np.mean(u[:SEARCH_SAMPLES]))
    if longest < 1 or x.size < 2:
        return None
    lags = list(range(min(longest, x.size - 1) + 1))
    r = shifted_dots(x, x, lags)
    if not r[0] > 0.0:
        return None
    r = r / r[0]
    fallen = np.flatnonzero(r < _DECORRELATED)
    if not fallen.size:
        return None
    back = np.flatnonzero(np.abs(r[fallen[0] :]) >= _REPEATS)
    if not back.size:
        return None
    repeat = int(fallen[0] + back[0])
    crossed = np.flatnonzero(r[:repeat] <= 0.0)
    return repeat, max(int(crossed[0]) - 1 if crossed.size else repeat - 1, 0)


def _separate_ties(sse: FloatArray, best: int, margin: float) -> list[int]:
    """Delays within ``margin`` that are not in the best delay's contiguous run."""
    near = np.isfinite(sse) & (sse <= margin)
    lo = hi = best
    while lo > 0 and near[lo - 1]:
        lo -= 1
    while hi + 1 < sse.size and near[hi + 1]:
        hi += 1
    return [int(k) for k in np.flatnonzero(near) if not lo <= k <= hi]


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
        Sum of squared errors (one-step or free-run, see ``criterion``) of each,
        over the same rows (inf where the candidate could not be fitted or diverged).
    criterion : str
        The rule, in words.
    repeat : int or None
        The lag at which the input repeats (:func:`input_repeat`), which bounded
        the delays tried below it; None when it does not repeat within the range.
    warning : str or None
        Why the chosen delay is not to be trusted: another, separate delay fits
        the record as well (the input's repeat or too little excitation).
    """

    delay: int
    delays: tuple[int, ...]
    sse: tuple[float, ...]
    criterion: str = ""
    repeat: int | None = None
    warning: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """``{"delay", "max_delay", "criterion", "repeat", "warning", "sse"}`` (JSON-safe)."""
        return {
            "delay": self.delay,
            "max_delay": self.delays[-1] if self.delays else 0,
            "criterion": self.criterion,
            "repeat": self.repeat,
            "warning": self.warning,
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
        The error compared: one-step prediction (default; the ARX delay, what
        the operating-point decision compares) or free-run simulation (the
        first order plus dead time equivalent; the least-squares default).

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
    samples are searched, and only delays shorter than the input's repeat
    (:func:`input_repeat`).

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
    # A delay as long as the input's repeat fits it as well as the true one
    # (sign flipped on a square wave's half period): never tried.
    repeats = input_repeat(u, max_delay)
    repeat = None if repeats is None else repeats[0]
    if repeats is not None:
        max_delay = min(max_delay, repeats[1])
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
    # A record whose squares overflow leaves inf/NaN sums: those candidates
    # cannot be fitted (error inf), and the SVD must not see them.
    unfit = ~(np.isfinite(Gs).all(axis=(1, 2)) & np.isfinite(rhs).all(axis=1))
    Gs[unfit] = 0.0
    W = (np.linalg.pinv(Gs, rcond=1e-13) @ (rhs * scale_cols)[..., None])[..., 0] * scale_cols
    W[unfit] = np.nan

    def exact(k: int, simulated: bool) -> float:
        ud = held[start[k] : start[k] + m]
        if simulated:
            drive = W[k, 1] * ud + (W[k, 2] if constant else 0.0)
            if constant:
                drive[: d[k]] += W[k, 3]
            with np.errstate(all="ignore"):
                from scipy.signal import lfilter

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
    # One-step errors from the normal equations, YᵀY - Wᵀ rhs; that difference
    # cancels to about 1e-13 YᵀY, so the few candidates near the least are
    # recomputed from their residuals.
    quick = np.maximum(YY - np.einsum("ki,ki->k", W, rhs), 0.0)
    quick[unfit | ~np.isfinite(quick)] = math.inf
    sse = quick.tolist()
    near = np.flatnonzero(quick <= 10.0 * float(quick.min()) + 1e-10 * YY)
    for k in near[:16].tolist() + np.argsort(quick)[:3].tolist():
        sse[k] = exact(int(k), simulated=False)
    scale = max(float(np.max(np.abs(ys))), 1e-300)
    rounding = Y.size * float(np.square(np.float64(1e-9 * scale)))  # inf, not an error
    best, margin = _smallest_near_best(np.asarray(sse), Y.size, rounding)
    warning = None
    if criterion == "simulation":
        # The first order plus dead time equivalent starts no earlier than the
        # first visible response (the one-step delay) and, the sensor's lag
        # being shorter than the transport delay on the kits it is for, no
        # later than twice it. Wider, the ARX estimates' noise bias let a
        # wrong delay simulate a square wave better.
        lo, hi = best, min(2 * best, max_delay)
        sse = [exact(k, simulated=True) if lo <= k <= hi else math.inf for k in range(nd)]
        best, margin = _smallest_near_best(np.asarray(sse), Y.size, rounding)
        ties = _separate_ties(np.asarray(sse), best, margin)
        if ties:
            others = ", ".join(map(str, ties[:5])) + (" ..." if len(ties) > 5 else "")
            warning = (
                note("delay_ambiguous_repeats", delay=best, others=others, repeat=repeat)
                if repeat is not None
                else note("delay_ambiguous", delay=best, others=others)
            )
    return DelaySearch(best, delays, tuple(sse), _CRITERIA[criterion], repeat, warning)
