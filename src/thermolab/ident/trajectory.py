"""The result of the block and recursive methods: estimates aligned with the samples."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError
from thermolab.jsonsafe import finite_or_none, json_safe

from .models import (
    INVALID_REASONS,
    NO_ESTIMATE,
    ArxOrder,
    FirstOrderModel,
    discrete_to_first_order,
)
from .operating_point import OperatingPoint

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["Trajectory"]

FloatArray = npt.NDArray[np.float64]


def _json_list(a: npt.NDArray[Any]) -> list[Any]:
    # json_safe's rule, vectorised: these arrays hold a value per sample (10^6 and more).
    obj = a.astype(object)
    obj[~np.isfinite(a)] = None
    out: list[Any] = obj.tolist()
    return out


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Parameter estimates of a block or recursive method, one row per sample.

    Alignment: row ``k`` holds the estimate that became available when sample
    ``k`` arrived (the newest target ``y[k]`` it uses), so the arrays have one
    entry per sample of the record and ``trajectory.k`` is ``0 .. n-1``.
    Samples before the first estimate, and estimates with no first-order
    meaning, hold NaN in ``K`` and ``tau``; ``valid`` says which rows hold a
    usable estimate and ``reason_code`` / :attr:`invalid_reason` why the others
    do not. ``W`` is NaN only where there is no estimate at all (an unstable
    model still has its ``W``).

    Parameters
    ----------
    method : str
        ``"blockls"``, ``"malsm"``, ``"wlsm"`` (or ``"lsm"``/``"srm"`` from an
        online identifier).
    dt : float
        Sample period in seconds.
    W : numpy.ndarray, shape (n_samples, n_params)
        Discrete parameters, columns named by ``param_names``.
    order : ArxOrder
        Model structure of ``W``.
    offset : str or float
        The offset mode the estimates were made with.
    param_names : tuple of str
        Names of ``W``'s columns.
    status : numpy.ndarray of int8, optional
        Per-row codes from the method that override the ones derived from ``W``
        where non-zero (2: the regression was singular, 6: the recursion
        diverged); see :data:`~thermolab.ident.models.INVALID_REASONS`.
    params : dict, optional
        The method's settings (``window``, ``gamma`` ...), for reports.
    operating_point : OperatingPoint, optional
        How ``offset="auto"`` decided the handling (None when it was given).
    warnings : tuple of str, optional
        What makes the estimates less trustworthy (implausible final values,
        windows across a gap in time, jitter, an undetermined operating point).

    Notes
    -----
    ``K``, ``tau``, ``valid`` and ``reason_code`` are derived from ``W`` with
    :func:`~thermolab.ident.models.discrete_to_first_order` when the trajectory
    is built.

    Examples
    --------
    >>> import numpy as np
    >>> W = np.array([[np.nan, np.nan], [0.9, 0.2], [0.9, 0.2], [1.1, 0.2]])
    >>> tr = Trajectory("malsm", 1.0, W, ArxOrder(), "initial", ("a", "b"))
    >>> tr.K.round(3), tr.valid
    (array([nan,  2.,  2., nan]), array([False,  True,  True, False]))
    >>> tr.invalid_reason[3][:30]
    'unstable or integrating model:'
    """

    method: str
    dt: float
    W: FloatArray
    order: ArxOrder
    offset: str | float
    param_names: tuple[str, ...]
    status: npt.NDArray[np.int8] | None = None
    params: dict[str, Any] = field(default_factory=dict)
    operating_point: OperatingPoint | None = None
    warnings: tuple[str, ...] = ()
    K: FloatArray = field(init=False)
    tau: FloatArray = field(init=False)
    reason_code: npt.NDArray[np.int8] = field(init=False)

    def __post_init__(self) -> None:
        K, tau, code = discrete_to_first_order(self.W, self.dt, self.order)
        if self.status is not None:
            override = self.status != 0
            code[override] = self.status[override]
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "tau", tau)
        object.__setattr__(self, "reason_code", code)

    @property
    def n_samples(self) -> int:
        """Number of samples (rows)."""
        return int(self.W.shape[0])

    @property
    def k(self) -> npt.NDArray[np.intp]:
        """Sample index of each row, ``0 .. n_samples-1``."""
        return np.arange(self.n_samples)

    @property
    def valid(self) -> npt.NDArray[np.bool_]:
        """True where the row holds an estimate with a first-order meaning."""
        out: npt.NDArray[np.bool_] = self.reason_code == 0
        return out

    @property
    def invalid_reason(self) -> npt.NDArray[np.object_]:
        """Per row, ``None`` when valid, else why not (a sentence)."""
        reasons = np.array(INVALID_REASONS, dtype=object)
        out: npt.NDArray[np.object_] = reasons[self.reason_code]
        return out

    @property
    def first_estimate(self) -> int | None:
        """Sample index of the first row holding an estimate (valid or not), or None."""
        has = ~np.isnan(self.W).all(axis=1) if self.W.shape[1] else np.zeros(0, bool)
        idx = np.flatnonzero(has)
        return int(idx[0]) if idx.size else None

    @property
    def final(self) -> FirstOrderModel:
        """The model at the last sample (its ``reason`` says why when it is not valid)."""
        if self.n_samples == 0:
            return FirstOrderModel(math.nan, math.nan, INVALID_REASONS[1])
        code = int(self.reason_code[-1])
        if code:
            return FirstOrderModel(math.nan, math.nan, INVALID_REASONS[code])
        return FirstOrderModel(
            float(self.K[-1]), float(self.tau[-1]), theta=self.order.delay * self.dt
        )

    @property
    def last_estimate(self) -> tuple[int | None, FirstOrderModel]:
        """The last sample that holds an estimate, and its model: the offline answer.

        On a complete record the samples after the last full block (or before
        the first full window) have no estimate of their own; the record's best
        answer is then the last estimate made, not "no estimate yet".
        ``(None, final)`` when no sample holds one.
        """
        has = np.flatnonzero(self.reason_code != NO_ESTIMATE)
        if not has.size:
            return None, self.final
        k = int(has[-1])
        code = int(self.reason_code[k])
        if code:
            return k, FirstOrderModel(math.nan, math.nan, INVALID_REASONS[code])
        return k, FirstOrderModel(
            float(self.K[k]), float(self.tau[k]), theta=self.order.delay * self.dt
        )

    @property
    def trusted(self) -> bool:
        """A valid final estimate and no warning: one to show as final."""
        return self.final.valid and not self.warnings

    def _series(self, name: str) -> FloatArray:
        if name == "K":
            return self.K
        if name == "tau":
            return self.tau
        raise InvalidParameterError(f"parameter must be 'K' or 'tau', got {name!r}")

    def _stabilisation(self, x: FloatArray, last: int) -> float:
        tail = x[-last:]
        tail = tail[np.isfinite(tail)]
        return float(tail.mean()) if tail.size else math.nan

    def converged_at(self, tol: float = 0.01, last: int = 2000) -> dict[str, int | None]:
        """First sample after which each estimate stays within ±tol of its stabilisation value.

        Parameters
        ----------
        tol : float, optional
            Relative tolerance, > 0 (default 0.01: the paper's ±1 %).
        last : int, optional
            The stabilisation value is the mean of the valid estimates over the
            last ``last`` samples (all of them if the record is shorter). Default 2000.

        Returns
        -------
        dict
            ``{"K": k or None, "tau": k or None}``: the sample index ``k`` of the
            first estimate such that it and every later estimate are valid and
            within ``±tol·|stabilisation value|``; None when even the last
            estimate is not (or there is no valid estimate). Rows holding no
            estimate (before the first one, between blocks) are skipped.

        Raises
        ------
        InvalidParameterError
            If ``tol`` is not > 0 or ``last`` is not a positive integer.

        Examples
        --------
        >>> import numpy as np
        >>> a = np.array([0.5, 0.8, 0.9, 0.9, 0.9])
        >>> W = np.column_stack([a, 0.2 * (1 - a)])
        >>> tr = Trajectory("wlsm", 1.0, W, ArxOrder(), "initial", ("a", "b"))
        >>> tr.converged_at(tol=0.01, last=3)
        {'K': 0, 'tau': 2}
        """
        _check_tol_last(tol, last)
        # Rows between block estimates hold no estimate (code 1); they neither break
        # nor make convergence. Every other row must be valid and inside the band.
        has_estimate = self.reason_code != 1
        out: dict[str, int | None] = {}
        for name in ("K", "tau"):
            x = self._series(name)
            ref = self._stabilisation(x, last)
            if not math.isfinite(ref):
                out[name] = None
                continue
            with np.errstate(invalid="ignore"):
                inside = np.abs(x - ref) <= tol * abs(ref)
            outside = np.flatnonzero(has_estimate & ~inside)
            after = outside[-1] + 1 if outside.size else 0
            rows = np.flatnonzero(has_estimate[after:])
            out[name] = int(after + rows[0]) if rows.size else None
        return out

    def after_convergence(self, tol: float = 0.01) -> dict[str, Any]:
        """Convergence as the paper counts it: statistics over the samples after it.

        :meth:`converged_at` and :meth:`stats` judge the last ``last`` samples,
        which on a record only a little longer than the transient still hold the
        start-up (WLSM(1) on the paper's 2000 samples: Ts mean 246.27, min
        26.74, "no convergence"). Here the stabilisation value is the mean of
        the estimates *after* convergence, found by fixed-point iteration: start
        from the median of the second half of the record, find where each
        estimate enters and stays in ``±tol`` of it, take the mean after the
        later of the two, and repeat until the convergence sample stops moving.

        Parameters
        ----------
        tol : float, optional
            Relative tolerance, > 0 (default 0.01: the paper's ±1 %).

        Returns
        -------
        dict
            ``converged`` (bool), ``converged_at`` (``{"K", "tau"}``: sample
            indices, or None), ``samples_after`` (samples after the later one)
            and ``stats`` (``{"K": {"mean", "max", "min"}, "tau": {...}}`` over
            those samples; NaN when it did not converge).

        Raises
        ------
        InvalidParameterError
            If ``tol`` is not > 0.

        Examples
        --------
        >>> import numpy as np
        >>> a = np.r_[np.linspace(0.5, 0.9, 50), np.full(100, 0.9)]
        >>> W = np.column_stack([a, 0.2 * (1 - a)])
        >>> r = Trajectory("wlsm", 1.0, W, ArxOrder(), "initial", ("a", "b")).after_convergence()
        >>> r["converged"], r["converged_at"], r["samples_after"]
        (True, {'K': 0, 'tau': 49}, 100)
        """
        _check_tol_last(tol, 1)
        n = self.n_samples
        has_estimate = self.reason_code != 1
        series = {name: self._series(name) for name in ("K", "tau")}
        refs: dict[str, float] = {}
        for name, x in series.items():
            half = x[n // 2 :]
            half = half[np.isfinite(half)]
            refs[name] = float(np.median(half)) if half.size else math.nan
        at: dict[str, int | None] = {"K": None, "tau": None}
        start = -1
        for _ in range(20):
            for name, x in series.items():
                at[name] = _entry(x, refs[name], tol, has_estimate)
            if at["K"] is None or at["tau"] is None:
                break
            later = max(at["K"], at["tau"])
            if later == start:
                break
            start = later
            for name, x in series.items():
                tail = x[start:]
                tail = tail[np.isfinite(tail)]
                refs[name] = float(tail.mean()) if tail.size else math.nan
        converged = at["K"] is not None and at["tau"] is not None
        stats: dict[str, dict[str, float]] = {}
        for name, x in series.items():
            # The samples after the convergence sample, as the paper's "2000 samples after
            # convergence" (thermolab reproduce table1's rows) count them.
            tail = x[start + 1 :] if converged else x[:0]
            tail = tail[np.isfinite(tail)]
            stats[name] = (
                {"mean": float(tail.mean()), "max": float(tail.max()), "min": float(tail.min())}
                if tail.size
                else {"mean": math.nan, "max": math.nan, "min": math.nan}
            )
        return {
            "converged": converged,
            "converged_at": at if converged else {"K": None, "tau": None},
            "samples_after": n - start - 1 if converged else 0,
            "stats": stats,
        }

    def stats(self, last: int = 2000) -> dict[str, dict[str, float]]:
        """Mean, maximum and minimum of the valid estimates over the last ``last`` samples.

        Parameters
        ----------
        last : int, optional
            Number of final samples to summarise (all when the record is shorter).
            Default 2000, as in the paper's tables.

        Returns
        -------
        dict
            ``{"K": {"mean", "max", "min"}, "tau": {...}}``; NaN when no valid
            estimate falls in the range.

        Raises
        ------
        InvalidParameterError
            If ``last`` is not a positive integer.

        Examples
        --------
        >>> import numpy as np
        >>> a = np.array([0.5, 0.8, 0.9, 0.9, 0.9])
        >>> W = np.column_stack([a, 0.2 * (1 - a)])
        >>> Trajectory("wlsm", 1.0, W, ArxOrder(), "initial", ("a", "b")).stats(last=3)["K"]
        {'mean': 0.2, 'max': 0.2, 'min': 0.2}
        """
        _check_tol_last(0.01, last)
        out: dict[str, dict[str, float]] = {}
        for name in ("K", "tau"):
            tail = self._series(name)[-last:]
            tail = tail[np.isfinite(tail)]
            if tail.size:
                out[name] = {
                    "mean": float(tail.mean()),
                    "max": float(tail.max()),
                    "min": float(tail.min()),
                }
            else:
                out[name] = {"mean": math.nan, "max": math.nan, "min": math.nan}
        return out

    def to_dict(
        self, *, arrays: bool = True, tol: float = 0.01, last: int = 2000
    ) -> dict[str, Any]:
        """A JSON-safe summary (NaN and inf become ``None``).

        Parameters
        ----------
        arrays : bool, optional
            Include the per-sample arrays ``K``, ``tau``, ``W``, ``valid`` and
            ``reason_code`` (with ``reasons`` to decode it). Default True.
        tol, last : optional
            Passed to :meth:`converged_at` and :meth:`stats`.

        Returns
        -------
        dict
            ``method``, ``dt``, ``order``, ``offset``, ``params``, ``param_names``,
            ``n_samples``, ``first_estimate``, ``final`` (``{"K", "tau", "valid",
            "reason"}``), ``stats``, ``converged_at``, ``after_convergence``,
            ``operating_point``, ``warnings``, ``trusted`` and, with ``arrays``, the arrays.

        Examples
        --------
        >>> import json, numpy as np
        >>> W = np.array([[np.nan, np.nan], [0.9, 0.2]])
        >>> d = Trajectory("malsm", 1.0, W, ArxOrder(), "initial", ("a", "b")).to_dict()
        >>> d["K"], d["final"]["K"], json.loads(json.dumps(d)) == d
        ([None, 2.0], 2.0, True)
        """
        stats = self.stats(last)
        out: dict[str, Any] = {
            "method": self.method,
            "dt": self.dt,
            "order": self.order.to_dict(),
            "offset": self.offset,
            "params": {k: json_safe(v) for k, v in self.params.items()},
            "param_names": list(self.param_names),
            "n_samples": self.n_samples,
            "first_estimate": self.first_estimate,
            "final": self.final.to_dict(),
            "stats": {p: {s: finite_or_none(v) for s, v in d.items()} for p, d in stats.items()},
            "converged_at": self.converged_at(tol, last),
            "after_convergence": _json_after(self.after_convergence(tol)),
            "operating_point": None
            if self.operating_point is None
            else self.operating_point.to_dict(),
            "warnings": list(self.warnings),
            "trusted": self.trusted,
        }
        if arrays:
            out["K"] = _json_list(self.K)
            out["tau"] = _json_list(self.tau)
            out["W"] = _json_list(self.W)
            out["valid"] = self.valid.tolist()
            out["reason_code"] = self.reason_code.tolist()
            out["reasons"] = list(INVALID_REASONS)
        return out

    def plot(self, *, reference: FirstOrderModel | None = None, title: str | None = None) -> Figure:
        """Parameter convergence, ``K`` and ``tau`` against the sample, like the paper's Figs. 9-11.

        Parameters
        ----------
        reference : FirstOrderModel, optional
            Draw its ``K`` and ``tau`` as dashed lines (the true plant, when known).
        title : str, optional
            Figure title; default names the method and its settings.

        Returns
        -------
        matplotlib.figure.Figure
            A figure not attached to pyplot (save it with ``fig.savefig(path)``).

        Raises
        ------
        ImportError
            If matplotlib is not installed (``pip install 'thermolab[plot]'``).
        """
        from ._plotting import plot_trajectory

        return plot_trajectory(self, reference=reference, title=title)


def _entry(
    x: FloatArray, ref: float, tol: float, has_estimate: npt.NDArray[np.bool_]
) -> int | None:
    """First row after which every estimate is valid and within ``±tol·|ref|`` (or None)."""
    if not math.isfinite(ref):
        return None
    with np.errstate(invalid="ignore"):
        inside = np.abs(x - ref) <= tol * abs(ref)
    outside = np.flatnonzero(has_estimate & ~inside)
    after = int(outside[-1]) + 1 if outside.size else 0
    rows = np.flatnonzero(has_estimate[after:])
    return after + int(rows[0]) if rows.size else None


def _json_after(r: dict[str, Any]) -> dict[str, Any]:
    stats = r["stats"]
    return {
        **r,
        "stats": {p: {k: finite_or_none(v) for k, v in d.items()} for p, d in stats.items()},
    }


def _check_tol_last(tol: object, last: object) -> None:
    if isinstance(tol, bool) or not isinstance(tol, int | float) or not (0.0 < tol < math.inf):
        raise InvalidParameterError(
            f"tol must be a relative tolerance > 0 (e.g. 0.01), got {tol!r}"
        )
    if isinstance(last, bool) or not isinstance(last, int | np.integer) or last < 1:
        raise InvalidParameterError(f"last must be a positive number of samples, got {last!r}")
