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
here therefore fits both and keeps the one that predicts the record better
(by an information criterion that charges the constant term its parameter):
``"initial"`` for an ambient start, the paper's procedure, ``"fit"``
otherwise. When the data cannot tell, the result says so and which option to
give.
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
from ._instrumental import instrumental_ambient
from .deadtime import DelaySearch, search_delay
from .models import ArxOrder
from .notes import note

__all__ = ["OperatingPoint", "decide_operating_point"]

FloatArray = npt.NDArray[np.float64]

Start = Literal["ambient", "settled", "moving", "unknown"]


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
    delay_search : DelaySearch or None
        The dead time search made with the chosen handling (None when the
        order was given).
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
    delay_search: DelaySearch | None = None

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
    moved = u != u[0]
    first = int(np.argmax(moved))  # the first True, without an index of every change
    return first if moved[first] else int(u.size)


def _ambient_with_stderr(
    u: FloatArray, y: FloatArray, order: ArxOrder
) -> tuple[float, float, float, float]:
    """The constant-term model's ambient ``c / (1 - sum(a))``, its stderr, gain and noise."""
    sol = _reg.solve_record(u, y, order, "fit")
    if not sol.ok:
        return math.nan, math.nan, math.nan, math.nan
    W = sol.W
    dof = sol.rows - W.size
    sigma2 = sol.rss / dof if dof > 0 else 0.0
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


def _one_step_sse(u: FloatArray, y: FloatArray, order: ArxOrder, offset: str) -> float:
    """Sum of squared one-step prediction errors of the least-squares model of ``order``."""
    return _reg.solve_record(u, y, order, offset).rss


def decide_operating_point(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    *,
    order: ArxOrder | None = None,
    max_delay: int = 0,
) -> OperatingPoint:
    """Decide from the record how its operating point is to be handled.

    Parameters
    ----------
    u, y : array_like
        Input and output in absolute volts, same length.
    dt : float
        Sample period in seconds, > 0.
    order : ArxOrder, optional
        The model structure the decision is for. Default: first order with the
        dead time searched over ``0 .. max_delay`` samples for each handling
        (:func:`thermolab.ident.deadtime.search_delay`).
    max_delay : int, optional
        Longest dead time searched when ``order`` is None (default 0).

    Returns
    -------
    OperatingPoint
        ``handling`` (the offset mode to use), ``start``, the ambient found, the
        dead time search of the chosen handling, and any warning.

    Raises
    ------
    InvalidDataError
        If the record is not finite or the lengths differ.
    InvalidParameterError
        If ``dt``, ``order`` or ``max_delay`` is not allowed.

    Notes
    -----
    The rule:

    1. The input never changes in the record (a step at the first sample):
       the constant term cannot be told from the gain, so the record is taken
       to start at ambient (``"initial"``, the paper's LSM(1)).
    2. Otherwise both handlings are fitted and their one-step prediction
       errors compared by the Bayesian information criterion
       ``m log(SSE/m) + p log(m)`` (``p`` parameters, one more for the constant
       term; errors below ``1e-9`` of the output's size count as rounding).
       The lower wins. (The free-run simulation error was tried and rejected:
       with measurement noise a free constant term absorbs the ARX bias and
       wins on records that start at rest, making the gain far worse.) ``"fit"`` is labelled
       ``"settled"`` when the output is flat (within the noise) until the input
       changes, else ``"moving"``.
    3. When the evidence is weak (the criteria differ by less than
       ``log(m)``), the input starts away from 0 V and the constant term's
       ambient is uncertain by more than the ``K u0`` that separates an ambient
       start from a settled one, the data cannot tell: a warning says so and
       which option to give (the default is then ``"fit"``, right for both when
       the record excites it). A ``"fit"`` whose ambient is uncertain by more
       than 5 % of the output's range is flagged as poorly determined (few
       samples before the step); if the input was off (0 V) before it changed,
       ``"initial"`` is used instead, with the same warning.
    4. A clear win of ``"fit"`` for a first order is checked against
       measurement noise, which biases least squares and lets a free constant
       term win on a record that starts at rest (a slow plant under a square
       wave: ``K`` three times low): the ambient is estimated again by
       instrumental variables (:mod:`thermolab.ident._instrumental`). Equal to
       ``y[0]`` within three standard errors, and not to the settled start's
       ``y[0] - K u0``, it means a start at rest (``"initial"``); equal to
       both, the data cannot tell and a warning says so.

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
    ord_given = None if order is None else _v.check_order(order)
    longest = _v.integer("max_delay", max_delay, 0, "0 turns the search off")
    lag = 0 if ord_given is None else ord_given.lag
    _v.check_min_samples(y_arr.size, lag + 5, "deciding the operating point")
    y0, u0 = float(y_arr[0]), float(u_arr[0])
    s = _first_change(u_arr)
    if s >= u_arr.size:
        search = search_delay(u_arr, y_arr, "initial", longest) if ord_given is None else None
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
            delay_search=search,
        )
    m = y_arr.size - 1 - lag
    scale = max(float(y_arr.max()), -float(y_arr.min()), 1e-300)  # max |y|, no copy
    floor = m * (1e-9 * scale) ** 2
    crit: dict[str, float] = {}
    searches: dict[str, DelaySearch] = {}
    n_dyn = 2 if ord_given is None else ord_given.na + ord_given.nb
    for handling in ("initial", "fit"):
        if ord_given is None:
            searches[handling] = search_delay(u_arr, y_arr, handling, longest)
            sse = min(searches[handling].sse)
        else:
            sse = _one_step_sse(u_arr, y_arr, ord_given, handling)
        p = n_dyn + int(handling == "fit")
        crit[handling] = m * math.log(max(sse, floor) / m) + p * math.log(m)
    chosen: Literal["initial", "fit"] = "initial" if crit["initial"] <= crit["fit"] else "fit"
    fit_order = ord_given if ord_given is not None else ArxOrder(1, 1, searches["fit"].delay)
    amb, se, gain, noise = _ambient_with_stderr(u_arr, y_arr, fit_order)
    span = float(np.ptp(y_arr))
    weak = abs(crit["initial"] - crit["fit"]) < math.log(m)
    notes: list[str] = []
    at_rest_by_iv = ""
    if chosen == "fit" and not weak and (fit_order.na, fit_order.nb) == (1, 1):
        # With measurement noise the constant term wins by absorbing least
        # squares' bias; an estimate free of it says where the record starts.
        iv = instrumental_ambient(u_arr, y_arr, fit_order.delay)
        if iv is not None:
            tol = 3.0 * iv.stderr + 1e-9 * scale
            at_rest = abs(iv.ambient - y0) <= tol
            settled = u0 != 0.0 and abs(iv.ambient - (y0 - iv.gain * u0)) <= tol
            if at_rest and not settled:
                chosen = "initial"
                at_rest_by_iv = (
                    f"the record starts at rest at ambient: the constant term's ambient "
                    f"estimated free of the noise bias ({iv.ambient:.4g} ± {iv.stderr:.2g} V, "
                    f"instrumental variables) is y[0] = {y0:.4g} V, not y[0] - K u[0]; the "
                    "fitted constant only predicted better by absorbing least squares' bias"
                )
            elif at_rest:
                notes.append(note("start_ambiguous", ambient=iv.ambient, stderr=iv.stderr, u0=u0))
    if weak and u0 != 0.0 and (not math.isfinite(se) or 3.0 * se > abs(gain * u0)):
        chosen = "fit"
        notes.append(note("start_too_early_fit", change=s, u0=u0, need=max(20, 2 * s + 10)))
    elif chosen == "fit" and u0 == 0.0 and (not math.isfinite(se) or se > 0.05 * span):
        # The input was off before it changed: a start at rest is the natural
        # reading, and a constant term this uncertain would ruin the gain.
        chosen = "initial"
        need = max(20, 2 * s + 10)
        notes.append(note("start_too_early_initial", change=s, ambient=amb, stderr=se, need=need))
    elif chosen == "fit" and (not math.isfinite(se) or se > 0.05 * span):
        need = max(20, 2 * s + 10)
        notes.append(note("constant_uncertain", ambient=amb, stderr=se, change=s, need=need))
    search = searches.get(chosen)
    if chosen == "initial":
        return OperatingPoint(
            "initial",
            "ambient",
            y0,
            se,
            y0,
            u0,
            s,
            at_rest_by_iv
            or "the record starts at rest at ambient: subtracting y[0] predicts the record "
            "as well as a fitted constant term does",
            tuple(notes),
            search,
        )
    pre = y_arr[: s + 1]
    flat = float(np.ptp(pre)) <= max(6.0 * noise, 1e-9 * scale)
    start: Start = "settled" if flat else "moving"
    if notes and notes[0].startswith("operating point undetermined"):
        start = "unknown"
    what = {
        "settled": f"settled under {u0:.4g} V",
        "moving": "moving (the output changes before the input does)",
        "unknown": "at an operating point the data cannot decide",
    }[start]
    return OperatingPoint(
        "fit",
        start,
        amb,
        se,
        y0,
        u0,
        s,
        f"the record starts {what}: a fitted constant term predicts the record better "
        "than subtracting y[0]",
        tuple(notes),
        search,
    )
