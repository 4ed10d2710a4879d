"""Recursive methods: moving-window least squares (MALSM) and weighted least squares (WLSM)."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError

from . import _regression as _reg
from . import _validation as _v
from ._trust import check_record, dead_time_params, rows_inside, with_warnings
from .models import ArxOrder
from .registry import SETTINGS, default_w0
from .trajectory import Trajectory

__all__ = ["moving_window_least_squares", "weighted_least_squares"]

FloatArray = npt.NDArray[np.float64]

#: The WLSM forms: the paper's eqs. 13-15, and textbook exponential-forgetting RLS.
WLSM_FORMS: tuple[str, ...] = SETTINGS["form"].choices


def window_rows(order: ArxOrder, window: int, n_params: int) -> int:
    """Regression rows inside a window of ``window`` samples, checking there are enough."""
    return rows_inside("window", order, window, n_params)


def check_recompute(recompute_every: object, rows: int) -> int:
    """The MALSM recomputation period in rows (default: the window's row count)."""
    if recompute_every is None:
        return rows
    return _v.integer("recompute_every", recompute_every, 1, "rows between exact recomputations")


def _shifted(y: FloatArray, shift: float) -> FloatArray:
    return y - shift if shift != 0.0 else y


def run_malsm(
    u: FloatArray, ys: FloatArray, order: ArxOrder, constant: bool, rows: int, every: int
) -> tuple[FloatArray, npt.NDArray[np.int8]]:
    """MALSM over a record already in the offset frame: ``(W, status)`` per sample."""
    from . import _kernels, _kernels_first_order

    n = ys.size
    p = order.na + order.nb + int(constant)
    first = order.is_first_order and not constant
    # Column-major, so that each parameter's trajectory is contiguous for the
    # vectorised conversion to (K, tau); the kernel writes every row from start on.
    W = np.empty((n, p), order="F")
    code = np.empty(n, dtype=np.int8)
    start = min(order.lag + 1, n)
    W[:start] = np.nan
    code[:start] = 1
    buf, sums, shift, ints = _kernels.malsm_state(rows, every, p, first)
    if first:
        _kernels_first_order.malsm2_chunk(u, ys, start, n, buf, sums, ints, W, code)
    else:
        _kernels.malsm_chunk(
            u, ys, start, n, order.na, order.nb, order.delay, constant,
            buf, sums, shift, ints, W, code,
        )  # fmt: skip
    return W, code


def run_wlsm(
    u: FloatArray,
    ys: FloatArray,
    order: ArxOrder,
    constant: bool,
    paper: bool,
    gamma: float,
    W0: FloatArray,
    P0: FloatArray,
) -> tuple[FloatArray, npt.NDArray[np.int8]]:
    """WLSM over a record already in the offset frame: ``(W, status)`` per sample."""
    from . import _kernels, _kernels_first_order

    n = ys.size
    p = W0.size
    W = np.empty((n, p), order="F")  # column-major: see run_malsm
    code = np.empty(n, dtype=np.int8)
    start = min(order.lag + 1, n)
    W[:start] = W0
    code[:start] = 0
    Wk = W0.copy()
    Pk = P0.copy()
    if order.is_first_order and not constant:
        _kernels_first_order.wlsm2_chunk(u, ys, start, n, paper, gamma, Wk, Pk, W, code)
    else:
        _kernels.wlsm_chunk(
            u, ys, start, n, order.na, order.nb, order.delay, constant, paper, gamma,
            Wk, Pk, W, code,
        )  # fmt: skip
    return W, code


def moving_window_least_squares(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    window: int = SETTINGS["window"].default,
    *,
    order: ArxOrder | None = None,
    offset: str | float = SETTINGS["offset"].default,
    recompute_every: int | None = SETTINGS["recompute_every"].default,
    t: npt.ArrayLike | None = None,
    expected_sign: int | None = SETTINGS["expected_sign"].default,
    max_delay: int | None = SETTINGS["max_delay"].default,
) -> Trajectory:
    """Moving-window least squares: the paper's MALSM, one estimate per sample.

    A FIFO window holds the last ``window`` samples; the estimate at sample
    ``k`` is the least-squares solution over the regression rows whose samples
    all lie in ``k-window+1 .. k`` (``window - 1 - order.lag`` rows: 99 for the
    paper's first-order window of 100). The first estimate is at sample
    ``window - 1``, then one at every sample.

    Parameters
    ----------
    u, y : array_like
        Input and output samples in absolute volts, same length.
    dt : float
        Sample period in seconds, > 0.
    window : int, optional
        Samples in the window, default 100; at least ``order.lag + 1 + n_params``.
    order : ArxOrder, optional
        Model structure. Default: first order with the dead time searched in
        the whole record as :func:`~thermolab.ident.least_squares` does
        (``params["dead_time"]``: ``"searched"`` or ``"given"``; ``params["delay"]``).
    offset : {"auto", "initial", "fit", "none"} or float, optional
        As in :func:`~thermolab.ident.least_squares` (``"initial"``: the record's
        first sample is the ambient, for every window). Default ``"auto"``,
        decided from the whole record (until this release ``"initial"``).
    recompute_every : int, optional
        Rows between exact recomputations of the running sums; default the
        window's row count (O(1) amortised cost per sample).
    t : array_like, optional
        Sample times: windows that span a gap in time, and jitter, are flagged.
    expected_sign : {1, -1}, optional
        The sign the gain must have; a final gain of the other sign is flagged.
    max_delay : int, optional
        Longest dead time searched when ``order`` is None (as in ``least_squares``).

    Returns
    -------
    Trajectory
        NaN before sample ``window - 1``; windows whose regression is singular
        (input constant and output settled inside the window) have reason code 2.

    Raises
    ------
    InvalidDataError
        If the data are not finite, differ in length, or are shorter than one window.
    InvalidParameterError
        If ``window``, ``dt``, ``order``, ``offset`` or ``recompute_every`` is not allowed.

    Notes
    -----
    Cost O(p²) per sample whatever the window (running sums of ``DᵀD`` and
    ``DᵀY`` taken about a shift and recomputed exactly every
    ``recompute_every`` rows, in a Numba-compiled loop). Each estimate equals a
    fresh SVD solve of its window to about ``κ² · ρ · 1e-16`` relative: ``κ``
    is the condition number of the window's regressor matrix with unit-norm
    columns (normal equations square it), ``ρ >= 1`` how much larger the
    values that passed through the sums since the last recomputation were than
    the window's own (about 1 for data at a steady level). Windows with ``κ``
    above about 1e6 are reported singular. For the paper's square wave
    (κ ≈ 8) that is 1e-14; for the tail of a settled step (κ ≈ 1e4), 1e-8.
    See :mod:`thermolab.ident._kernels`.

    Examples
    --------
    The paper's MALSM row: a 4↔6 V square wave at 0.1 Hz, window 100.

    >>> import numpy as np
    >>> from thermolab.simulation import REFERENCE_MODEL
    >>> u = np.where((np.arange(2000) // 5) % 2 == 0, 6.0, 4.0)
    >>> tr = moving_window_least_squares(u, REFERENCE_MODEL.simulate(u), 1.0, window=100)
    >>> tr.first_estimate, int(tr.valid.sum())
    (99, 1901)
    >>> s = tr.stats()
    >>> round(s["K"]["min"], 6), round(s["K"]["max"], 6), round(s["tau"]["min"], 6)
    (0.14009, 0.14009, 250.126233)
    """
    u_arr, y_arr, step, ord_, off, op, search = check_record(u, y, dt, order, offset, max_delay)
    size = _v.integer("window", window, 1, "samples in the moving window")
    constant = off == "fit"
    p = ord_.na + ord_.nb + int(constant)
    rows = window_rows(ord_, size, p)
    every = check_recompute(recompute_every, rows)
    _v.check_min_samples(y_arr.size, size, f"one window of {size} samples")
    shift, _ = _reg.offset_shift(off, float(y_arr[0]))
    W, code = run_malsm(u_arr, _shifted(y_arr, shift), ord_, constant, rows, every)
    tr = Trajectory(
        method="malsm",
        dt=step,
        W=W,
        order=ord_,
        offset=off,
        param_names=ord_.param_names(constant=constant),
        status=np.where(code == 2, code, 0).astype(np.int8),
        params={"window": size, "recompute_every": every, **dead_time_params(search, ord_)},
        operating_point=op,
    )
    return with_warnings(
        tr, op, t, expected_sign, window=size, search=search, record=(u_arr, y_arr), memory=size
    )


def check_wlsm_params(
    gamma: object,
    pmax: object,
    w0: object,
    form: object,
    p0: object,
    n_params: int,
    n_dynamic: int,
) -> tuple[float, FloatArray, FloatArray, bool]:
    """Validate WLSM settings; return ``(gamma, W0, P0, paper)``."""
    if form not in WLSM_FORMS:
        raise InvalidParameterError(
            f"form must be one of {', '.join(repr(f) for f in WLSM_FORMS)}, got {form!r}"
        )
    paper = form == "paper"
    g = _v.real("gamma", gamma)
    if paper:
        if g == 1.0:
            raise InvalidParameterError(
                "gamma = 1 is not allowed in the paper's form: alpha = 1 - gamma = 0 makes 1/alpha "
                "in eq. 13 meaningless; use form='standard' (ordinary RLS without forgetting) "
                "or a gamma in (0, 1)"
            )
        if not 0.0 < g < 1.0:
            raise InvalidParameterError(
                f"gamma (forgetting factor) must be in (0, 1) for the paper's form, got {g!r}"
            )
    elif not 0.0 < g <= 1.0:
        raise InvalidParameterError(f"gamma (forgetting factor) must be in (0, 1], got {g!r}")
    pm = _v.real("pmax", pmax)
    if not (math.isfinite(pm) and pm > 0.0):
        raise InvalidParameterError(
            f"pmax (initial diagonal of P) must be finite and > 0, got {pm!r}"
        )
    if w0 is None:
        W0 = np.array(default_w0(n_dynamic, n_params))
    else:
        try:
            W0 = np.asarray(w0, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise InvalidParameterError(f"w0 must be a list of numbers, got {w0!r}") from None
        if W0.size == n_dynamic and n_params == n_dynamic + 1:
            W0 = np.append(W0, 0.0)  # the constant term of offset="fit" starts at 0
        if W0.size != n_params:
            allowed = f"{n_dynamic} or {n_params}" if n_params != n_dynamic else f"{n_params}"
            raise InvalidParameterError(
                f"w0 must have {allowed} entries (one per parameter), got {W0.size}"
            )
        if not np.isfinite(W0).all():
            raise InvalidParameterError(f"w0 must be finite, got {W0.tolist()!r}")
    if p0 is None:
        P0 = np.eye(n_params) * pm
    elif paper:
        raise InvalidParameterError(
            "p0 is only for form='standard'; the paper's form starts from P = pmax·I"
        )
    else:
        P0 = _check_p0(p0, n_params)
    return g, W0, P0, paper


def _check_p0(p0: object, n_params: int) -> FloatArray:
    if isinstance(p0, bool):
        raise InvalidParameterError(f"p0 must be a number or a matrix, got {p0!r}")
    try:
        arr = np.asarray(p0, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidParameterError(f"p0 must be a number or a matrix, got {p0!r}") from None
    if arr.ndim == 0:
        v = float(arr)
        if not (math.isfinite(v) and v > 0.0):
            raise InvalidParameterError(
                f"p0 (initial covariance) must be finite and > 0, got {v!r}"
            )
        return np.eye(n_params) * v
    if arr.shape != (n_params, n_params):
        raise InvalidParameterError(
            f"p0 must be a scalar or a {n_params}x{n_params} matrix, got shape {arr.shape}"
        )
    if not np.isfinite(arr).all() or not np.array_equal(arr, arr.T):
        raise InvalidParameterError("p0 must be a finite symmetric matrix")
    try:
        np.linalg.cholesky(arr)
    except np.linalg.LinAlgError:
        raise InvalidParameterError("p0 must be positive definite") from None
    return arr.copy()


def weighted_least_squares(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    gamma: float = SETTINGS["gamma"].default,
    pmax: float = SETTINGS["pmax"].default,
    w0: npt.ArrayLike | None = None,
    *,
    form: Literal["paper", "standard"] = SETTINGS["form"].default,
    p0: float | npt.ArrayLike | None = SETTINGS["p0"].default,
    order: ArxOrder | None = None,
    offset: str | float = SETTINGS["offset"].default,
    t: npt.ArrayLike | None = None,
    expected_sign: int | None = SETTINGS["expected_sign"].default,
    max_delay: int | None = SETTINGS["max_delay"].default,
) -> Trajectory:
    """Weighted (recursive) least squares with a forgetting factor: the paper's WLSM.

    ``form="paper"`` runs the paper's eqs. 13-15 as corrected in the reading
    notes, literally::

        α = 1 - γ
        K = (P/γ) D (1/α + Dᵀ (P/γ) D)⁻¹
        W ← W + K (y - Dᵀ W)
        P ← (1/γ) (I - K Dᵀ) P,        P0 = pmax·I

    ``form="standard"`` runs textbook exponential-forgetting RLS,
    ``K = P D / (γ + Dᵀ P D)``, ``P ← (P - K DᵀP)/γ``, from ``P0 = p0`` (or
    ``pmax·I`` when ``p0`` is not given). The two are the same algorithm: the
    paper's form with ``pmax`` equals the standard one with
    ``P0 = (1 - γ)·pmax·I``. So the paper's ``pmax`` is *not* an initial
    covariance in the usual (e.g. MATLAB ``InitialParameterCovariance``) sense.

    Parameters
    ----------
    u, y : array_like
        Input and output samples in absolute volts, same length.
    dt : float
        Sample period in seconds, > 0.
    gamma : float, optional
        Forgetting factor: in (0, 1) for the paper's form (γ = 1 makes α = 0),
        in (0, 1] for the standard form (1: no forgetting). Default 0.96, the
        paper's WLSM(1) (declared in :mod:`thermolab.ident.registry`).
    pmax : float, optional
        Diagonal of the initial ``P``, finite and > 0; default 1e4 (WLSM(1)).
    w0 : array_like, optional
        Initial parameters. Default: the paper's ``[0.96329, 9.9082e-4]`` for
        the first-order ``[a, b]`` regressor, zeros for other orders (see
        :func:`~thermolab.ident.registry.default_w0`). With ``offset="fit"`` a
        missing constant starts at 0.
    form : {"paper", "standard"}, optional
        Which formulation to run; default ``"paper"``.
    p0 : float or array_like, optional
        Standard form only: the initial covariance, a scalar (times I) or a
        symmetric positive-definite matrix.
    order : ArxOrder, optional
        Model structure. Default: first order with the dead time searched in
        the whole record as :func:`~thermolab.ident.least_squares` does
        (``params["dead_time"]``: ``"searched"`` or ``"given"``; ``params["delay"]``).
    offset : {"auto", "initial", "fit", "none"} or float, optional
        As in :func:`~thermolab.ident.least_squares`; default ``"auto"``,
        decided from the whole record (until this release ``"initial"``).
    t : array_like, optional
        Sample times: gaps and jitter are flagged.
    expected_sign : {1, -1}, optional
        The sign the gain must have; a final gain of the other sign is flagged.
    max_delay : int, optional
        Longest dead time searched when ``order`` is None (as in ``least_squares``).

    Returns
    -------
    Trajectory
        ``W0`` at sample 0 (and up to ``order.lag``), then the estimate updated
        with the row whose target is sample ``k`` at every sample ``k``. If the
        recursion overflows, the rest of the rows have reason code 6.

    Raises
    ------
    InvalidDataError
        If the data are not finite, differ in length, or are too short for one update.
    InvalidParameterError
        If ``gamma`` (including γ = 1 in the paper's form), ``pmax``, ``w0``,
        ``p0``, ``form``, ``dt``, ``order`` or ``offset`` is not allowed.

    Examples
    --------
    The paper's WLSM(2): a 0↔4 V square wave, γ = 0.7, pmax = 1e4.

    >>> import numpy as np
    >>> from thermolab.simulation import REFERENCE_MODEL, PAPER_W0
    >>> u = np.where((np.arange(3000) // 5) % 2 == 0, 4.0, 0.0)
    >>> y = REFERENCE_MODEL.simulate(u)
    >>> tr = weighted_least_squares(u, y, 1.0, gamma=0.7, pmax=1e4, w0=PAPER_W0)
    >>> print(tr.final)
    FirstOrderModel(K=0.14009..., tau=250.126233..., reason=None, theta=0.0)
    >>> tr.converged_at()["K"] < 100
    True
    """
    u_arr, y_arr, step, ord_, off, op, search = check_record(u, y, dt, order, offset, max_delay)
    constant = off == "fit"
    n_dyn = ord_.na + ord_.nb
    p = n_dyn + int(constant)
    g, W0, P0, paper = check_wlsm_params(gamma, pmax, w0, form, p0, p, n_dyn)
    _v.check_min_samples(y_arr.size, ord_.lag + 2, f"one WLSM update with order {ord_}")
    shift, _ = _reg.offset_shift(off, float(y_arr[0]))
    W, code = run_wlsm(u_arr, _shifted(y_arr, shift), ord_, constant, paper, g, W0, P0)
    params: dict[str, object] = {"gamma": g, "pmax": float(pmax), "form": form}
    params["w0"] = W0.tolist()
    if p0 is not None:
        params["p0"] = P0.tolist()
    params.update(dead_time_params(search, ord_))
    tr = Trajectory(
        method="wlsm",
        dt=step,
        W=W,
        order=ord_,
        offset=off,
        param_names=ord_.param_names(constant=constant),
        status=np.where(code == 6, code, 0).astype(np.int8),
        params=params,
        operating_point=op,
    )
    # Forgetting by gamma per sample: the final estimate rests on about
    # 1/(1 - gamma) samples (at least the model's own few).
    memory = max(round(1.0 / (1.0 - g)) if g < 1.0 else y_arr.size, p + ord_.lag + 1)
    return with_warnings(
        tr, op, t, expected_sign, search=search, record=(u_arr, y_arr), memory=memory
    )
