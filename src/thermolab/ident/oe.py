"""Output-error fit of a first-order plus dead time model: the unbiased alternative.

The paper's methods minimise the *equation error* ``y[k+1] - a y[k] - b u[k]``,
which regresses on the measured (noisy) output: with measurement noise the
estimate is biased towards a faster, smaller-gain model (with 5 mV of noise, Ts
about 6 % low on a step and 12 % low on a square wave — the paper's Table II
lesson). The *output error* fit here minimises the error of the model's free-run
simulation instead, which never feeds the noise back, so it is consistent for
white measurement noise (Ljung, *System Identification*, 2nd ed., §4.2).

Model (exact behind the zero-order hold; the input before the record is held at
``u[0]``):

    x[k+1] = a x[k] + b1 u[k-d] + b2 u[k-d-1],   y[k] = ambient + x[k],

with ``a = exp(-dt/tau)``, ``theta = d dt + phi`` (``0 <= phi < dt``),
``b1 = K (1 - exp(-(dt - phi)/tau))`` and ``b2 = K (exp(-(dt - phi)/tau) - a)``.
The free parameters are ``K``, ``tau``, ``theta``, the ambient and, unless the
record starts at rest at ambient (decided as for ``offset="auto"`` by
:mod:`thermolab.ident.operating_point`), the initial deviation ``x[0]`` with
the input before the record (which the dead time carries into the first
samples): right for a record that starts at ambient, settled under an input or
moving.
:func:`scipy.optimize.least_squares` (trust region reflective, bounds on
``tau`` and ``theta``) minimises the simulation error, started from the
least-squares (ARX) estimate with its dead time search.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import numpy.typing as npt

# SciPy is imported inside the functions that use it: at import, scipy.signal and
# scipy.optimize cost every lab, rig host and command 0.8 s of start-up.
from thermolab.errors import InsufficientExcitationError, InvalidParameterError

from . import _validation as _v
from . import diagnostics as _diag
from ._warning import IdentificationWarning
from .batch import least_squares
from .deadtime import default_max_delay
from .models import ArxOrder, FirstOrderModel
from .notes import note
from .oe_result import OutputErrorResult
from .registry import SETTINGS

__all__ = [
    "output_error",
    "output_error_at_rest",
    "simulate_fopdt",
    "simulate_fopdt_at",
]

FloatArray = npt.NDArray[np.float64]


def simulate_fopdt(
    u: FloatArray,
    K: float,
    tau: float,
    theta: float,
    dt: float,
    x0: float = 0.0,
    u_before: float | None = None,
) -> FloatArray:
    """Deviation ``x`` of the sampled FOPDT model from ambient, for input ``u``.

    The input before the record is held at ``u_before`` (default ``u[0]``);
    ``x[0] = x0``.

    Examples
    --------
    >>> import numpy as np
    >>> simulate_fopdt(np.r_[0.0, np.ones(5)], 1.0, 1.0, 1.5, 1.0).round(4)
    array([0.    , 0.    , 0.    , 0.3935, 0.7769, 0.9179])
    """
    d = int(theta // dt)
    phi = theta - d * dt
    a = math.exp(-dt / tau)
    rest = math.exp(-(dt - phi) / tau)
    b1, b2 = K * (1.0 - rest), K * (rest - a)
    n = u.size
    past = u[0] if u_before is None else u_before
    held = np.concatenate([np.full(d + 1, past), u])
    drive = b1 * held[1:n] + b2 * held[: n - 1]
    out: FloatArray = np.empty(n)
    out[0] = x0
    if n > 1:
        from scipy.signal import lfilter

        out[1:] = lfilter([1.0], [1.0, -a], drive, zi=[a * x0])[0]
    return out


def simulate_fopdt_at(
    t: FloatArray,
    u: FloatArray,
    K: float,
    tau: float,
    theta: float,
    x0: float = 0.0,
    u_before: float | None = None,
) -> FloatArray:
    """Deviation ``x`` of the FOPDT model at the recorded time stamps ``t``.

    Exact for an input held from each time stamp to the next (jitter, gaps):
    the delayed input changes at ``t[i] + theta``, between samples as often as
    not, so the model is stepped over the merged grid of both. The input
    before the record is held at ``u_before`` (default ``u[0]``); ``x[0] = x0``.
    On evenly spaced times it agrees with :func:`simulate_fopdt`.

    Examples
    --------
    >>> import numpy as np
    >>> u = np.r_[0.0, np.ones(5)]
    >>> x = simulate_fopdt_at(np.arange(6.0), u, 1.0, 1.0, 1.5)
    >>> bool(np.allclose(x, simulate_fopdt(u, 1.0, 1.0, 1.5, 1.0), atol=1e-12))
    True
    """
    past = float(u[0]) if u_before is None else float(u_before)
    shifted = t + theta
    grid = np.union1d(t, shifted[(shifted > t[0]) & (shifted < t[-1])])
    # Which recorded input drives each grid interval (-1: the input before the record);
    # a margin so that t[j] + theta - theta lands on sample j, not before it.
    margin = 1e-9 * max(float(np.max(np.abs(t))), 1.0)
    idx = np.searchsorted(t, grid - theta + margin, side="right") - 1
    v = np.where(idx >= 0, u[np.maximum(idx, 0)], past)
    a = np.exp(-np.diff(grid) / tau)
    drive = (K * (1.0 - a) * v[:-1]).tolist()
    x = [x0]
    last = x0
    for ak, dk in zip(a.tolist(), drive, strict=True):
        last = ak * last + dk
        x.append(last)
    out: FloatArray = np.asarray(x)[np.searchsorted(grid, t)]
    return out


def output_error(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    *,
    theta: float | None = SETTINGS["theta"].default,
    max_delay: int | None = SETTINGS["max_delay"].default,
    expected_sign: int | None = SETTINGS["expected_sign"].default,
    t: npt.ArrayLike | None = None,
) -> OutputErrorResult:
    """Fit ``K exp(-theta s) / (tau s + 1)`` by minimising the free-run simulation error.

    Parameters
    ----------
    u, y : array_like
        Input and output in absolute volts, one per sample period, same length.
    dt : float
        Sample period in seconds, > 0.
    theta : float, optional
        The dead time in seconds, if known (fixed); default: estimated, between
        0 and ``max_delay`` samples.
    max_delay : int, optional
        Longest dead time considered, in samples (default as in
        :func:`thermolab.ident.least_squares`).
    expected_sign : {1, -1}, optional
        The sign the gain must have; the other sign is flagged.
    t : array_like, optional
        The sample times (s), strictly increasing. Jitter and gaps are flagged
        as by :func:`thermolab.ident.least_squares`, and where they are found
        the model is simulated at these times (:func:`simulate_fopdt_at`)
        instead of every ``dt``.

    Returns
    -------
    OutputErrorResult

    Raises
    ------
    InvalidDataError
        If the record is not finite, the lengths differ or it holds fewer than 20 samples.
    InsufficientExcitationError
        If the input never changes (the gain cannot be told from the ambient) or
        the starting least-squares fit has no first-order meaning.
    InvalidParameterError
        If ``dt``, ``theta`` or ``max_delay`` is not allowed.

    Warns
    -----
    IdentificationWarning
        Implausible estimates, failed residual tests, an optimiser that did not converge.

    Examples
    --------
    A step with 12.5 s of dead time and 5 mV of noise:

    >>> import numpy as np
    >>> t = np.arange(1500)
    >>> u = np.where(t >= 20, 8.0, 0.0)
    >>> x = simulate_fopdt(u, 0.14, 250.0, 12.5, 1.0)
    >>> y = 0.3 + x + np.random.default_rng(3).normal(0, 0.005, t.size)
    >>> r = output_error(u, y, 1.0)
    >>> abs(r.K / 0.14 - 1) < 0.02, abs(r.tau / 250 - 1) < 0.05, abs(r.theta - 12.5) < 1.5
    (True, True, True)
    """
    return _fit(u, y, dt, theta, max_delay, expected_sign, t, at_rest=False)


def output_error_at_rest(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    *,
    t: npt.ArrayLike | None = None,
) -> OutputErrorResult:
    """:func:`output_error` with the kit at rest at its ambient, input off, before the record.

    The initial state is not fitted, whatever the data say: what a record
    means when its notebook says the kit was cold before it. A record whose
    model differs from this one depends on what came before it.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(-1.0, 700.0); u = np.where(t >= 0, 50.0, 0.0)
    >>> y = 21.0 + simulate_fopdt_at(t, u, 0.6, 140.0, 15.0)
    >>> r = output_error_at_rest(u, y, 1.0, t=t)
    >>> round(r.K, 3), round(r.tau, 1), round(r.theta, 1)
    (0.6, 140.0, 15.0)
    """
    defaults = SETTINGS["theta"].default, SETTINGS["max_delay"].default
    return _fit(u, y, dt, *defaults, SETTINGS["expected_sign"].default, t, at_rest=True)


def _fit(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    theta: float | None,
    max_delay: int | None,
    expected_sign: int | None,
    t: npt.ArrayLike | None,
    *,
    at_rest: bool,
) -> OutputErrorResult:
    u_arr, y_arr = _v.as_record(u, y)
    step = _v.check_dt(dt)
    n = y_arr.size
    _v.check_min_samples(n, 20, "the output-error fit")
    timing: list[str] = []
    t_arr: FloatArray | None = None
    if t is not None:
        t_arr, steps = _v.check_time_steps(t, n)
        timing = _diag.timing_warnings_from_steps(t_arr, steps)
    if np.all(u_arr == u_arr[0]):
        raise InsufficientExcitationError(note("oe_no_excitation"))
    longest = (
        default_max_delay(n)
        if max_delay is None
        else _v.integer("max_delay", max_delay, 0, "0: no dead time")
    )
    fixed_theta = None
    if theta is not None:
        fixed_theta = _v.real("theta", theta)
        if not (math.isfinite(fixed_theta) and 0.0 <= fixed_theta <= 0.5 * n * step):
            raise InvalidParameterError(
                f"theta (dead time) must be from 0 to half the record ({0.5 * n * step:g} s), "
                f"got {fixed_theta!r}"
            )
        start_order: ArxOrder | None = ArxOrder(1, 1, int(fixed_theta // step))
    else:
        start_order = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        arx = least_squares(u_arr, y_arr, step, order=start_order, max_delay=longest, holdout=0.0)
    # An ambient start fixes the initial state (at rest, input off before the
    # record); otherwise it is free. Both free on a record that starts at rest
    # would make the ambient, the initial state and the gain indistinguishable
    # after a single step.
    at_rest = at_rest or (
        arx.operating_point is not None and arx.operating_point.handling == "initial"
    )
    if not arx.model.valid:
        raise InsufficientExcitationError(
            f"the output-error fit needs a starting model, and least squares gave none: "
            f"{arx.model.reason}"
        )
    theta_hi = max(longest * step, 0.0) + step
    duration = n * step
    tau_lo, tau_hi = 0.05 * step, 100.0 * duration
    K0, tau0 = arx.K, float(np.clip(arx.tau, 1.01 * tau_lo, 0.99 * tau_hi))
    amb0 = arx.ambient
    x00 = 0.0 if at_rest else float(y_arr[0]) - amb0
    th0 = arx.theta if fixed_theta is None else fixed_theta
    th0 = float(min(max(th0, 0.0), theta_hi * 0.999))
    scale_y = max(float(np.std(y_arr)), 1e-12)

    # Not at rest: the initial state and the input before the record (which the
    # dead time carries into the first samples) are free too.
    names = ["K", "log_tau", "ambient"] + ([] if at_rest else ["x0", "u_before"])
    names += ["theta"] if fixed_theta is None else []

    def unpack(p: FloatArray) -> tuple[float, float, float, float, float, float]:
        v = dict(zip(names, (float(x) for x in p), strict=True))
        th = fixed_theta if fixed_theta is not None else v["theta"]
        past = v.get("u_before", 0.0)
        return v["K"], math.exp(v["log_tau"]), th, v["ambient"], v.get("x0", 0.0), past

    def residual(p: FloatArray) -> FloatArray:
        K, tau, th, amb, x0, past = unpack(p)
        if timing and t_arr is not None:
            x = simulate_fopdt_at(t_arr, u_arr, K, tau, th, x0, past)
        else:
            x = simulate_fopdt(u_arr, K, tau, th, step, x0, past)
        r: FloatArray = amb + x - y_arr
        return r

    first = {"K": K0, "log_tau": math.log(tau0), "ambient": amb0, "x0": x00, "theta": th0}
    first["u_before"] = float(u_arr[0])
    lower = {"log_tau": math.log(tau_lo), "theta": 0.0}
    upper = {"log_tau": math.log(tau_hi), "theta": theta_hi}
    widths = {"K": max(abs(K0), 1e-6), "log_tau": 0.1, "ambient": scale_y, "x0": scale_y}
    widths["theta"] = step
    widths["u_before"] = max(float(np.ptp(u_arr)), 1e-12)
    p0 = [first[k] for k in names]
    lo = [lower.get(k, -np.inf) for k in names]
    hi = [upper.get(k, np.inf) for k in names]
    x_scale = [widths[k] for k in names]
    from scipy.optimize import least_squares as _scipy_least_squares

    best = _scipy_least_squares(
        residual,
        np.array(p0),
        bounds=(np.array(lo), np.array(hi)),
        x_scale=np.array(x_scale),
        method="trf",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=400,
    )
    K, tau, th, amb, x0, _ = unpack(best.x)
    res = -best.fun
    model = FirstOrderModel(K, tau, theta=th)
    stderr = _stderr(best.jac, res, names)
    stderr["tau"] = tau * stderr.pop("log_tau", math.nan)
    stderr.pop("u_before", None)
    sim = y_arr - res
    fit = _diag.fit_percent(y_arr, sim)
    # The optimiser stops at about 1e-6 of the output (its tolerances), not at
    # rounding: errors below that are an exact fit, not a failed test.
    # (A record too short for 25 lags and 10 samples more gets no residual test, as in LSM.)
    rtest = (
        _diag.residual_test(res, u_arr, scale=1e3 * max(float(np.max(np.abs(y_arr))), 1e-300))
        if res.size >= 36
        else None
    )
    notes = _diag.plausibility_warnings(K, tau, step, duration, expected_sign=expected_sign)
    if rtest is not None and not rtest.passed:
        if not rtest.independent:
            notes.append(note("oe_residual_input", bound=rtest.bound))
        else:
            notes.append(note("oe_residual_not_white", bound=rtest.bound))
    if not best.success:
        notes.append(note("optimiser_stopped", message=best.message))
    # The same words as every method; this fit simulated at the recorded times.
    notes += timing
    for said in notes:
        warnings.warn(said, IdentificationWarning, stacklevel=2)
    return OutputErrorResult(
        model=model,
        ambient=amb,
        x0=x0,
        stderr=stderr,
        fit_simulation=fit,
        residual_test=rtest,
        start=arx.order,
        n_samples=n,
        dt=step,
        nfev=int(best.nfev),
        warnings=tuple(notes),
        y_simulated=sim,
        residuals=res,
    )


def _stderr(jac: FloatArray, res: FloatArray, names: list[str]) -> dict[str, float]:
    """Gauss-Newton standard errors ``sqrt(diag(s² (JᵀJ)⁻¹))`` of the parameters."""
    dof = res.size - len(names)
    out = dict.fromkeys(["K", "log_tau", "theta", "ambient", "x0"], math.nan)
    if dof <= 0:
        return out
    s2 = float(res @ res) / dof
    try:
        cov = s2 * np.linalg.pinv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return out
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    for name, value in zip(names, se, strict=True):
        out[name] = float(value)
    return out
