"""The operating point of a record, decided from the data (``offset="auto"``).

An ARX model in absolute volts needs to know where the plant rests with the
input off (the ambient). Three kinds of record reach the lab:

* **at ambient**: the record starts at rest with the input off (the paper's
  cold rig), or the input is switched on at the first sample. Subtracting
  ``y[0]`` (``offset="initial"``) is exact and costs no parameter;
* **settled under a nonzero input**: ``y[0]`` is ``ambient + K u0``, so
  subtracting it while regressing on the absolute input makes ``K`` wrong (60 %
  low on a 5→8 V step);
* **moving** (a warm rig still cooling or heating): nothing at the start is an
  equilibrium.

A constant term (``y[k+1] = a y[k] + b u[k] + c``, ``offset="fit"``) is right
in all three cases when the record excites it, but costs a parameter that is
poorly determined when few samples precede the input change. The procedure
here therefore fits the constant-term model once and asks whether its ambient
``c / (1 - a)`` agrees with ``y[0]`` within its own standard error (and the
noise): if so the record started at ambient and ``"initial"`` is used, the
paper's procedure; if not, ``"fit"``. When the constant term is too poorly
determined to tell, the result says so and which option to give.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from thermolab.jsonsafe import finite_or_none

from . import _regression as _reg
from . import _validation as _v
from .models import ArxOrder

__all__ = ["OperatingPoint", "decide_operating_point"]

FloatArray = npt.NDArray[np.float64]

Start = Literal["ambient", "settled", "moving", "unknown"]

# Agreement of the fitted ambient with y[0], in standard errors (about 99.7 %).
_AGREE_SIGMAS = 3.0


@dataclass(frozen=True)
class OperatingPoint:
    """How a record's operating point was handled, and what was found.

    Attributes
    ----------
    handling : {"initial", "fit"}
        The offset mode used: ``"initial"`` subtracts ``y[0]`` (a record that
        starts at ambient), ``"fit"`` estimates a constant term.
    start : {"ambient", "settled", "moving", "unknown"}
        How the record starts: at ambient, settled under a nonzero input, moving,
        or not decidable from the data.
    ambient : float
        The output at rest with the input off: ``y[0]`` for ``"initial"``, the
        constant term's ``c / (1 - sum(a))`` for ``"fit"`` (NaN if not estimable).
    ambient_stderr : float
        Standard error of the constant-term model's ambient (NaN when not fitted).
    y0, u0 : float
        First output and input samples.
    samples_before_change : int
        Samples recorded before the input first changes.
    reason : str
        One sentence: why this handling.
    warnings : tuple of str
        What makes the handling uncertain, with the option to choose.
    """

    handling: Literal["initial", "fit"]
    start: Start
    ambient: float
    ambient_stderr: float
    y0: float
    u0: float
    samples_before_change: int
    reason: str
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: every attribute, ``warnings`` as a list, NaN as ``None``.

        Examples
        --------
        >>> import numpy as np
        >>> u = np.r_[np.zeros(20), np.full(300, 5.0)]
        >>> y = np.zeros(320)
        >>> y[21:] = 0.5 * (1 - 0.9 ** np.arange(1, 300))
        >>> d = decide_operating_point(u, y, 1.0).to_dict()
        >>> d["handling"], d["start"], d["ambient"]
        ('initial', 'ambient', 0.0)
        """
        return {
            "handling": self.handling,
            "start": self.start,
            "ambient": finite_or_none(self.ambient),
            "ambient_stderr": finite_or_none(self.ambient_stderr),
            "y0": self.y0,
            "u0": self.u0,
            "samples_before_change": self.samples_before_change,
            "reason": self.reason,
            "warnings": list(self.warnings),
        }


def noise_level(y: FloatArray) -> float:
    """Robust standard deviation of white noise on ``y`` (from second differences).

    The median absolute deviation of the second differences ignores a smooth
    trend; the second difference of white noise has variance ``6 sigma²``.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> y = np.linspace(0, 1, 5000) + rng.normal(0, 0.01, 5000)
    >>> abs(noise_level(y) - 0.01) < 0.001
    True
    """
    if y.size < 4:
        return 0.0
    dd = np.diff(y, 2)
    return float(np.median(np.abs(dd - np.median(dd))) / 0.6745 / math.sqrt(6.0))


def _first_change(u: FloatArray) -> int:
    """Samples before the input first changes (``u.size`` if it never does)."""
    moved = np.flatnonzero(u != u[0])
    return int(moved[0]) if moved.size else int(u.size)


def _ambient_with_stderr(
    u: FloatArray, y: FloatArray, order: ArxOrder
) -> tuple[float, float, float, float]:
    """The constant-term model's ambient ``c / (1 - sum(a))``, its stderr, gain and noise."""
    reg = _reg.build(u, y, order, "fit")
    sol = _reg.solve(reg.D, reg.Y)
    if not sol.ok:
        return math.nan, math.nan, math.nan, math.nan
    W = sol.W
    res = reg.Y - reg.D @ W
    dof = reg.Y.size - W.size
    sigma2 = float(res @ res) / dof if dof > 0 else 0.0
    Vs = sol.Vt.T / sol.s
    cov = sigma2 * (Vs @ Vs.T) / np.outer(sol.norms, sol.norms)
    na = order.na
    den = 1.0 - float(W[:na].sum())
    if not den > 0.0:
        return math.nan, math.nan, math.nan, math.nan
    c = float(W[-1])
    grad = np.zeros(W.size)
    grad[:na] = c / den**2
    grad[-1] = 1.0 / den
    gain = float(W[na : na + order.nb].sum()) / den
    se = math.sqrt(max(float(grad @ cov @ grad), 0.0))
    return c / den, se, gain, math.sqrt(sigma2)


def decide_operating_point(
    u: npt.ArrayLike, y: npt.ArrayLike, dt: float, *, order: ArxOrder | None = None
) -> OperatingPoint:
    """Decide from the record how its operating point is to be handled.

    Parameters
    ----------
    u, y : array_like
        Input and output in absolute volts, same length.
    dt : float
        Sample period in seconds, > 0.
    order : ArxOrder, optional
        The model structure the decision is for; default first order.

    Returns
    -------
    OperatingPoint
        ``handling`` (the offset mode to use), ``start``, the ambient found and
        any warning (a poorly determined constant term, an undecidable start).

    Raises
    ------
    InvalidDataError
        If the record is not finite or the lengths differ.
    InvalidParameterError
        If ``dt`` or ``order`` is not allowed.

    Notes
    -----
    The rule, in order:

    1. The input never changes in the record (a step at the first sample):
       the constant term cannot be told from the gain, so the record is taken
       to start at ambient (``"initial"``, the paper's LSM(1)).
    2. Otherwise the constant-term model is fitted; its ambient ``c / (1 - a)``
       agreeing with ``y[0]`` within ``3`` standard errors means an ambient start: ``"initial"``. Disagreeing means
       ``"fit"``, labelled ``"settled"`` when the output is flat (within the
       noise) until the input changes, else ``"moving"``.
    3. When the two starts the data must tell apart, at ambient and settled
       under the first input ``u0``, have ambients closer than twice that
       tolerance (``|K u0|`` small beside the constant term's uncertainty), or
       the constant term cannot be estimated, a warning says so and which
       option to give; the default is then ``"initial"`` when the input starts
       at 0 V and ``"fit"`` otherwise.

    Examples
    --------
    A 5→8 V step from a settled start (ambient 1 V, K = 0.5):

    >>> import numpy as np
    >>> u = np.r_[np.full(50, 5.0), np.full(400, 8.0)]
    >>> y = np.full(450, 3.5)
    >>> y[51:] += 1.5 * (1 - 0.95 ** np.arange(1, 400))
    >>> op = decide_operating_point(u, y, 1.0)
    >>> op.handling, op.start, round(op.ambient, 6)
    ('fit', 'settled', 1.0)
    """
    u_arr, y_arr = _v.as_record(u, y)
    _v.check_dt(dt)
    ord_ = _v.check_order(order)
    _v.check_min_samples(y_arr.size, ord_.lag + 5, "deciding the operating point")
    y0, u0 = float(y_arr[0]), float(u_arr[0])
    s = _first_change(u_arr)
    if s >= u_arr.size:
        return OperatingPoint(
            "initial",
            "ambient",
            y0,
            math.nan,
            y0,
            u0,
            s,
            "the input is constant through the record (a step at the first sample), so the "
            "record is taken to start at rest at ambient (offset='initial')",
        )
    amb, se, gain, noise = _ambient_with_stderr(u_arr, y_arr, ord_)
    scale = max(1.0, abs(y0), float(np.ptp(y_arr)))
    tolerance = max(_AGREE_SIGMAS * se, 1e-9 * scale)
    # An ambient start and a start settled under u0 differ by K u0 in the ambient:
    # when that is inside the uncertainty, the data cannot tell them apart.
    if not math.isfinite(se) or (u0 != 0.0 and abs(gain * u0) <= 2.0 * tolerance):
        guess: Literal["initial", "fit"] = "initial" if u0 == 0.0 else "fit"
        detail = f" (ambient {amb:.4g} ± {se:.2g} V)" if math.isfinite(se) else ""
        note = (
            f"operating point undetermined: only {s} sample{'s' if s != 1 else ''} before the "
            f"input changes, so the constant term is poorly determined{detail}; assumed "
            f"offset='{guess}'. Give offset='initial' if the record starts at rest with the "
            "input off, offset='fit' if it starts settled under an input or moving, or the "
            f"known ambient in volts; better, record at least {max(20, 2 * s + 10)} samples "
            "before the step"
        )
        return OperatingPoint(
            guess,
            "unknown",
            y0 if guess == "initial" else amb,
            se,
            y0,
            u0,
            s,
            "the data cannot tell an ambient start from a settled one",
            (note,),
        )
    if abs(amb - y0) <= tolerance:
        return OperatingPoint(
            "initial",
            "ambient",
            y0,
            se,
            y0,
            u0,
            s,
            f"the constant-term model's ambient {amb:.6g} V agrees with y[0] = {y0:.6g} V "
            f"(within {tolerance:.2g} V): the record starts at rest at ambient",
        )
    pre = y_arr[: s + 1]
    flat = float(np.ptp(pre)) <= max(6.0 * noise, 1e-9 * scale)
    start: Start = "settled" if flat else "moving"
    what = (
        f"settled under {u0:.4g} V" if flat else "moving (the output changes before the input)"
    )
    return OperatingPoint(
        "fit",
        start,
        amb,
        se,
        y0,
        u0,
        s,
        f"the constant-term model's ambient {amb:.6g} V differs from y[0] = {y0:.6g} V by "
        f"more than {tolerance:.2g} V: the record starts {what}, so a constant term is fitted",
    )
