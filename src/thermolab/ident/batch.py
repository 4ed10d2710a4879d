"""Batch least squares over a whole record: the paper's eq. 12 (LSM).

The result class is in :mod:`~thermolab.ident.lsm_result`; least squares over
blocks (LSM(2), LSM(3)) in :mod:`~thermolab.ident.blocks`, re-exported here.
"""

from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidParameterError

from . import _regression as _reg
from . import _validation as _v
from . import diagnostics as _diag
from ._warning import IdentificationWarning
from .arx import ArxModel
from .deadtime import DEFAULT_CRITERION, DelaySearch, default_max_delay, search_delay
from .lsm_result import LeastSquaresResult
from .models import ArxOrder, FirstOrderModel
from .operating_point import OperatingPoint, decide_operating_point
from .registry import SETTINGS

if TYPE_CHECKING:
    pass

__all__ = ["LeastSquaresResult", "least_squares"]

FloatArray = npt.NDArray[np.float64]


def _spread(y: FloatArray) -> float:
    """``||y - mean(y)||``: the denominator of the NRMSE fit."""
    with np.errstate(all="ignore"):
        return float(np.linalg.norm(y - y.mean()))


def _fit_percent(spread: float, err: float) -> float:
    """NRMSE fit in percent from ``||y - mean(y)||`` and ``||y - ŷ||``."""
    if spread == 0.0:
        return math.nan
    if not math.isfinite(err):
        return -math.inf
    return 100.0 * (1.0 - err / spread)


def _nrmse_fit(y: FloatArray, yhat: FloatArray) -> float:
    with np.errstate(all="ignore"):
        return _fit_percent(_spread(y), float(np.linalg.norm(y - yhat)))


def _simulate(
    u: FloatArray, y: FloatArray, order: ArxOrder, y_shift: float, W: FloatArray
) -> FloatArray:
    """Free-run simulation of the identified model over the targets, in the offset frame.

    Started from the record's first ``lag + 1`` outputs and driven by ``u``.
    """
    from scipy.signal import lfilter, lfiltic

    na = order.na
    lag = order.lag
    drive = _reg.input_drive(u, order, W, y.size - 1 - lag)
    den = np.concatenate([[1.0], -W[:na]])
    head = y[: lag + 1] - y_shift
    if na == 1:
        # The filter's one state is what the past output adds to the first target.
        zi = np.array([W[0] * head[lag]])
    else:
        zi = lfiltic([1.0], den, head[lag - na + 1 : lag + 1][::-1])
    with np.errstate(all="ignore"):
        out: FloatArray = lfilter([1.0], den, drive, zi=zi)[0]
    return out


def _propagated_stderr(
    W: FloatArray, cov: FloatArray, order: ArxOrder, dt: float, model: FirstOrderModel
) -> tuple[float, float]:
    """Delta-method standard errors of the DC gain and of the dominant time constant."""
    if not model.valid or not np.isfinite(cov).all():
        return math.nan, math.nan
    na, nb = order.na, order.nb
    a, b = W[:na], W[na : na + nb]
    den = 1.0 - float(a.sum())
    g_K = np.zeros(W.size)
    g_K[:na] = float(b.sum()) / den**2
    g_K[na : na + nb] = 1.0 / den
    p = math.exp(-dt / model.tau)  # the dominant pole
    # Implicit differentiation of A(p) = p^na - sum a_i p^(na-i) = 0.
    powers = np.array([p ** (na - i) for i in range(1, na + 1)])
    dA = na * p ** (na - 1) - sum(a[i - 1] * (na - i) * p ** (na - i - 1) for i in range(1, na))
    g_tau = np.zeros(W.size)
    g_tau[:na] = dt / (p * math.log(p) ** 2) * powers / dA
    var_K = float(g_K @ cov @ g_K)
    var_tau = float(g_tau @ cov @ g_tau)
    return math.sqrt(max(var_K, 0.0)), math.sqrt(max(var_tau, 0.0))


def least_squares(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    *,
    order: ArxOrder | None = None,
    offset: str | float = SETTINGS["offset"].default,
    max_delay: int | None = SETTINGS["max_delay"].default,
    expected_sign: int | None = SETTINGS["expected_sign"].default,
    holdout: float = SETTINGS["holdout"].default,
    t: npt.ArrayLike | None = None,
) -> LeastSquaresResult:
    """Batch least squares over the whole record: the paper's LSM, eq. 12.

    Solves ``min ||Y - D W||`` with ``Y(k) = y[k+1]`` and ``D(k) = [y[k], u[k]]``
    (first order) by the SVD of ``D`` with unit-norm columns — the same
    ``W = (DᵀD)⁻¹DᵀY`` as eq. 12 without forming ``DᵀD`` or any inverse, so an
    ill-conditioned record loses ``cond(D)`` digits, not ``cond(D)²``.

    Parameters
    ----------
    u, y : array_like
        Input and output samples in absolute volts, one per sample period, same length.
    dt : float
        Sample period in seconds, > 0.
    order : ArxOrder, optional
        Model structure. Default: first order with the dead time chosen from
        the data (:func:`thermolab.ident.deadtime.search_delay`: the least
        free-run simulation error over ``0 .. max_delay`` samples, below the
        input's repeat); give ``ArxOrder(1, 1, 0)`` for eq. 4 exactly.
    offset : {"auto", "initial", "fit", "none"} or float, optional
        How the operating point is handled:

        * ``"auto"`` (default): decided from the record by
          :func:`thermolab.ident.operating_point.decide_operating_point`
          (``"initial"`` for a record that starts at ambient, ``"fit"`` for one
          that starts settled under an input or moving); the result's
          ``operating_point`` says which and why. Until this release the
          default was ``"initial"``;
        * ``"initial"``: ``y[0]`` is the ambient equilibrium at 0 V
          input and is subtracted from ``y`` (right for a record that starts
          from rest, the paper's procedure);
        * ``"fit"``: a constant term ``c`` is estimated with the other
          parameters; ``ambient = c / (1 - sum(a))``;
        * ``"none"``: the paper's raw form (correct only when the ambient is 0 V);
        * a float: the known ambient output in volts, subtracted from ``y``.
    max_delay : int, optional
        Longest dead time tried when ``order`` is None, in samples; default
        :func:`thermolab.ident.deadtime.default_max_delay` (60, at most a tenth
        of the record).
    expected_sign : {1, -1}, optional
        The sign the gain must have (1 for a heater); a gain of the other sign is
        flagged. Default None: not checked.
    holdout : float, optional
        Fraction of the record held out for ``fit_holdout`` (0 to 0.5; default
        0.3; 0 skips it).
    t : array_like, optional
        The sample times, if known: an irregular axis (jitter, gaps) is flagged.

    Returns
    -------
    LeastSquaresResult
        ``W``, ``model`` (``K``, ``tau``), standard errors, condition numbers,
        residuals and fit percentages.

    Raises
    ------
    InvalidDataError
        If ``u`` or ``y`` holds NaN/inf, they differ in length, or there are fewer
        samples than the order needs (``lag + 1 + n_params``).
    InsufficientExcitationError
        If ``D`` is rank-deficient: the input was held constant (e.g. kept at 0 V)
        or the output never moved, so ``DᵀD`` is singular.
    InvalidParameterError
        If ``dt``, ``order``, ``offset``, ``max_delay``, ``expected_sign`` or
        ``holdout`` is not allowed.

    Warns
    -----
    IdentificationWarning
        For each entry of the result's ``warnings``: failed residual tests,
        implausible estimates, a poorly determined operating point, timing jitter.

    Notes
    -----
    The model may come out unstable (``a >= 1``) on a badly excited noisy
    record; that is a result, not an error: ``model.valid`` is False and
    ``model.reason`` says why.

    Examples
    --------
    The paper's LSM(1): a 0→10 V step on the reference model, 2000 samples.

    >>> import numpy as np
    >>> from thermolab.simulation import REFERENCE_MODEL
    >>> u = np.full(2001, 10.0)
    >>> y = REFERENCE_MODEL.simulate(u)
    >>> r = least_squares(u, y, 1.0)
    >>> round(r.K, 6), round(r.tau, 6), round(r.fit_simulation, 3)
    (0.14009, 250.126233, 100.0)

    The same step from a warm ambient of 2.5 V gives the same model:

    >>> r = least_squares(u, y + 2.5, 1.0)
    >>> round(r.K, 6), round(r.tau, 6), r.ambient
    (0.14009, 250.126233, 2.5)
    """
    u_arr, y_arr = _v.as_record(u, y)
    step = _v.check_dt(dt)
    off_in = _v.check_offset_or_auto(offset)
    held = _v.real("holdout", holdout)
    if not 0.0 <= held <= 0.5:
        raise InvalidParameterError(f"holdout must be a fraction from 0 to 0.5, got {held!r}")
    timing = None if t is None else _v.check_time_steps(t, y_arr.size)
    search: DelaySearch | None = None
    longest = 0
    if order is None:
        if max_delay is None:
            longest = default_max_delay(y_arr.size)
        else:
            longest = _v.integer("max_delay", max_delay, 0, "0 turns the search off")
            if longest > 1000 or longest > y_arr.size // 4:
                raise InvalidParameterError(
                    f"max_delay must be at most 1000 and a quarter of the record "
                    f"({y_arr.size // 4} samples), got {longest}"
                )
    op: OperatingPoint | None = None
    if off_in == _v.AUTO_OFFSET:
        op = decide_operating_point(
            u_arr,
            y_arr,
            step,
            order=None if order is None else _v.check_order(order),
            max_delay=longest,
        )
        off: str | float = op.handling
    else:
        off = off_in
    if order is None and longest > 0:
        # The delay of the first order that best reproduces the record (its
        # FOPDT-equivalent dead time), not the ARX one-step delay, which stops
        # at the first visible response when the sensor adds a lag.
        search = search_delay(u_arr, y_arr, off, longest, DEFAULT_CRITERION)
    if order is None:
        ord_ = ArxOrder(1, 1, 0 if search is None else search.delay)
    else:
        ord_ = _v.check_order(order)
    p = ord_.na + ord_.nb + int(off == "fit")
    _v.check_min_samples(
        y_arr.size, ord_.lag + 1 + p, f"least squares of {p} parameters with order {ord_}"
    )
    sol = _reg.solve_record(u_arr, y_arr, ord_, off)
    if not sol.ok:
        raise _reg.excitation_error(sol, u_arr, y_arr, ord_)
    W = sol.W
    first_target = ord_.lag + 1
    # The arrays the result keeps are computed once each, and shifted back to
    # absolute volts in place when their offset-frame values have been used:
    # on 10⁷ samples every extra full-length array costs 80 MB and a pass.
    targets = y_arr[first_target:] - sol.y_shift  # Y, in the offset frame
    one_step = _reg.predict(u_arr, y_arr, ord_, sol.y_shift, W)
    residuals = targets - one_step
    spread = _spread(targets)
    with np.errstate(all="ignore"):
        fit_one = _fit_percent(spread, float(np.linalg.norm(residuals)))
    dof = sol.rows - p
    sigma2 = float(residuals @ residuals) / dof if dof > 0 else math.nan
    # (DᵀD)⁻¹ = N⁻¹ V Σ⁻² Vᵀ N⁻¹ with N the column norms of the equilibration.
    Vs = sol.Vt.T / sol.s
    inv_gram = (Vs @ Vs.T) / np.outer(sol.norms, sol.norms)
    cov = sigma2 * inv_gram
    stderr = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    na, nb = ord_.na, ord_.nb
    c = float(W[-1]) if sol.constant else 0.0
    arx = ArxModel(
        a=tuple(float(x) for x in W[:na]),
        b=tuple(float(x) for x in W[na : na + nb]),
        dt=step,
        delay=ord_.delay,
        c=c,
    )
    model = arx.first_order()
    K_se, tau_se = _propagated_stderr(W, cov, ord_, step, model)
    sim = _simulate(u_arr, y_arr, ord_, sol.y_shift, W)
    ambient = arx.ambient if sol.constant else sol.y_shift
    scale = max(float(y_arr.max()), -float(y_arr.min()), 1e-300)  # max |y|, no copy
    rtest = (
        _diag.residual_test(residuals, u_arr[first_target:], scale=scale)
        if sol.rows >= 36
        else None
    )
    with np.errstate(all="ignore"):
        error = np.subtract(targets, sim)
        fit_sim = _fit_percent(spread, float(np.linalg.norm(error)))
    del error
    fit_held = _holdout_fit(u_arr, y_arr, ord_, off, sol.y_shift, held) if held else math.nan
    notes = list(op.warnings) if op is not None else []
    if search is not None and search.warning:
        notes.append(search.warning)
    notes += _diag.plausibility_warnings(
        model.K, model.tau, step, y_arr.size * step, expected_sign=expected_sign
    )
    if rtest is not None:
        advice = _diag.residual_advice(rtest, search is not None or ord_.delay > 0)
        if advice:
            notes.append(advice)
    if timing is not None:
        notes += _diag.timing_warnings_from_steps(*timing)
    for said in notes:
        warnings.warn(said, IdentificationWarning, stacklevel=2)
    return LeastSquaresResult(
        W=W,
        param_names=ord_.param_names(constant=sol.constant),
        order=ord_,
        offset=off,
        dt=step,
        model=model,
        arx=arx,
        stderr=stderr,
        K_stderr=K_se,
        tau_stderr=tau_se,
        cond=float(sol.s_raw[0] / sol.s_raw[-1]),
        cond_scaled=float(sol.s[0] / sol.s[-1]),
        k=np.arange(first_target, y_arr.size),
        y_measured=_absolute(targets, sol.y_shift),
        y_one_step=_absolute(one_step, sol.y_shift),
        y_simulated=_absolute(sim, sol.y_shift),
        residuals=residuals,
        fit_one_step=fit_one,
        fit_simulation=fit_sim,
        n_samples=int(y_arr.size),
        ambient=float(ambient),
        y_shift=sol.y_shift,
        operating_point=op,
        delay_search=search,
        residual_test=rtest,
        fit_holdout=fit_held,
        warnings=tuple(notes),
    )


def _absolute(values: FloatArray, y_shift: float) -> FloatArray:
    """``values + y_shift`` in place (the same numbers as a new sum), returned."""
    values += y_shift
    return values


def _holdout_fit(
    u: FloatArray,
    y: FloatArray,
    order: ArxOrder,
    offset: str | float,
    y_shift: float,
    fraction: float,
) -> float:
    """Fit % of the free run over the last ``fraction`` by a model fitted to the rest."""
    n = y.size
    split = round(n * (1.0 - fraction))
    p = order.na + order.nb + int(offset == "fit")
    if split - order.lag - 1 < 3 * p or n - split < 10:
        return math.nan
    if np.ptp(u[split - order.delay - order.nb :]) == 0.0:
        return math.nan  # nothing excites the held-out part: its fit % means nothing
    # The shift of the whole record, so the two parts share one frame.
    frame: str | float = y_shift if offset == "initial" else offset
    first = _reg.solve_record(u[:split], y[:split], order, frame)
    if not first.ok:
        return math.nan
    start = split - order.lag - 1
    tail_u, tail_y = u[start:], y[start:]
    shift, _ = _reg.offset_shift(frame, float(tail_y[0]))
    sim = _simulate(tail_u, tail_y, order, shift, first.W)
    return _nrmse_fit(tail_y[order.lag + 1 :] - shift, sim)
