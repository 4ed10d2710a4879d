"""SRM: the step response method.

A first-order plant answering a step of ``ΔU`` volts moves its output by
``Δy = K ΔU`` along ``1 - exp(-t/tau)``. The method reads ``K`` from the final
value and ``tau`` as the time the output takes to cover 63.2 % of its change.
:func:`step_response` finds the step, the baseline and the final value in the
record itself and reports two gains: the paper's (the last sample of a finite
record) and a settled estimate extrapolated from the tail of the response.

The method's parts: :mod:`thermolab.ident._step_detect` reads the record (the
step, the noise), :mod:`thermolab.ident._step_fit` fits the tail and finds the
crossings, :mod:`thermolab.ident.step_result` holds what it found.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import numpy.typing as npt

from thermolab.errors import InsufficientExcitationError, InvalidDataError, InvalidParameterError

from ._step_detect import find_step, first_response, median_dt, noise_level, pre_step_drift
from ._step_fit import LEVEL_28, LEVEL_63, MIN_TAIL, crossing_time, fit_exponential_tail
from ._validation import as_record, check_time, integer, real
from ._warning import IdentificationWarning
from .diagnostics import plausibility_warnings
from .notes import note
from .step_result import StepResponseResult

__all__ = ["IdentificationWarning", "StepResponseResult", "step_response"]


# Huge readings overflow squares and sums to inf; the checks below see it and
# say so in a warning instead of a RuntimeWarning.
@np.errstate(all="ignore")
def step_response(
    t: npt.ArrayLike,
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    *,
    u_initial: float | None = None,
    min_step: float = 1.0,
    min_samples: int = 2000,
    settle_time_constants: float = 4.0,
) -> StepResponseResult:
    """Identify ``K`` and ``tau`` from a step response (SRM).

    Parameters
    ----------
    t : array_like
        Sample times in seconds, strictly increasing (jitter is fine).
    u, y : array_like
        Input and output samples in absolute volts, same length as ``t``. ``y[k]``
        is read before ``u[k]`` is applied (the record convention of
        :mod:`thermolab.simulation`).
    u_initial : float, optional
        The input before the record began. Give it when the step coincides with
        the first sample (``u`` then never changes inside the record).
    min_step : float, optional
        Steps smaller than this many volts are flagged (default 1 V, the paper's rule).
    min_samples : int, optional
        Records shorter than this are flagged (default 2000, the paper's rule; 0
        turns the check off).
    settle_time_constants : float, optional
        The record counts as settled when it lasts at least this many time
        constants after the step (default 4: within 1.8 % of the final value).

    Returns
    -------
    StepResponseResult
        Gains (settled and last-sample), time constant, the step found and the
        warnings.

    Raises
    ------
    InsufficientExcitationError
        If the input never changes (no step), or the output does not respond.
    InvalidDataError
        If the record is not finite, the lengths differ, ``t`` is not strictly
        increasing, the input changes more than once, or fewer than 6 samples
        follow the step.
    InvalidParameterError
        If an option is out of range.

    Warns
    -----
    IdentificationWarning
        When the record has not settled, the step is under ``min_step``, the record
        is shorter than ``min_samples``, the output was moving before the step, the
        record ends before the 63.2 % crossing, the few samples after the step give
        no sound fit (``K`` or ``tau`` not a finite positive time constant), or the
        response the figures describe misses the record. Each is also in
        ``warnings``; a result with any of them is not ``trusted``.

    Notes
    -----
    *Step.* The largest sample-to-sample change of ``u`` is the step; any other
    change above 10 % of it is refused as a second step. ``u_before`` and
    ``u_after`` are the mean input on each side.

    *Baseline.* The mean output from the first sample up to and including the
    step sample (which has not answered yet). Starting from rest (the paper's
    cold rig) makes it the operating point.

    *Final value.* The paper takes the last sample; a finite record stops short
    of the final value by ``exp(-T/tau)`` of the change, which is the paper's
    Table I deviation. The settled estimate fits ``y_inf - c exp(-(t - t0)/tau)``
    by least squares to the tail (from the first 63.2 % crossing of the
    last-sample change to the end; at least 6 samples) and takes ``y_inf``. The
    fit is a separable least-squares problem, linear in ``y_inf`` and ``c``, so
    only ``tau`` is searched (a log grid, then Brent's method): exact on an
    exponential, and averaging noise over the whole tail.

    *Time constant.* The crossing of ``baseline + (1 - 1/e) Δy`` (``Δy`` the settled
    change) between samples ``j-1`` and ``j`` is interpolated linearly in
    ``log(y_inf - y)``, the log of the remaining distance, which is linear in
    time for an exponential; the interpolation is therefore exact on a noise-free
    first-order response, wherever the samples fall. If a remaining distance is
    not positive (noise), it falls back to linear interpolation.

    *Settled.* The response left after ``T`` seconds is ``exp(-T/tau)`` of the
    change; ``settle_time_constants = 4`` means 1.8 %.

    *Table I.* For the reference model (K = 0.140090, tau = 250.126233 s, dt = 1 s)
    the paper's SRM gain 0.140042 is a last-sample value and its Ts the exact
    time constant. The last sample after ``m`` samples of step input is
    ``10 K (1 - a**m)``; rounded to 6 digits, as the paper rounds elsewhere
    (its W0 gives Ks = 0.0269905 and Ts = 26.73742, which truncation would make
    0.0269904 and 26.73741), this is 0.140042 only for m = 1994...1998. A
    2000-sample record ``t = 0 ... 1999`` s that starts at 0 V and steps to 10 V at
    ``t = 1`` s (``step:0:10@1``, the application's START-then-change-set-point
    procedure) has m = 1998: K_last_sample = 0.1400424 -> 0.140042. Stepping at
    ``t = 0`` instead gives m = 1999 (0.1400426) and a 2001-sample record to
    ``t = 2000`` s gives m = 2000 (0.1400428): both round to 0.140043, and match
    the printed figure only if it was truncated. The paper's Ts needs the settled
    change: the 63.2 % of the last-sample change would give 249.98 s.

    Examples
    --------
    The paper's simulated SRM run: 2000 samples, a 0→10 V step at ``t = 1`` s.

    >>> import numpy as np
    >>> from thermolab.simulation import REFERENCE_MODEL
    >>> t = np.arange(2000.0)
    >>> u = np.where(t >= 1.0, 10.0, 0.0)
    >>> r = step_response(t, u, REFERENCE_MODEL.simulate(u))
    >>> round(r.K_last_sample, 6), round(r.K, 6), round(r.tau, 6)
    (0.140042, 0.14009, 250.126233)
    >>> r.step_time, r.amplitude, r.direction, r.settled
    (1.0, 10.0, 'heating', True)

    A cooling step from an operating point, recorded for only 2.5 time constants:

    >>> import warnings
    >>> t = np.arange(700.0)
    >>> u = np.where(t >= 50, -5.0, 5.0)
    >>> y = REFERENCE_MODEL.simulate(u, y0=3.0 + 5 * 0.14009, ambient=3.0)
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     r = step_response(t, u, y)
    >>> round(r.K, 6), round(r.tau, 6), r.direction, r.settled
    (0.14009, 250.126233, 'cooling', False)
    >>> round(r.K_last_sample, 4)
    0.1296
    >>> [w.split(":")[0] for w in r.warnings]
    ['not settled', 'short record']
    """
    u_arr, y_arr = as_record(u, y)
    t_arr = check_time(t, u_arr.size)
    n = t_arr.size
    min_step_v = real("min_step", min_step)
    if not (math.isfinite(min_step_v) and min_step_v >= 0.0):
        raise InvalidParameterError(
            f"min_step must be a finite number of volts >= 0, got {min_step_v!r}"
        )
    min_samples_v = integer("min_samples", min_samples, 0, "0 turns the check off")
    settle = real("settle_time_constants", settle_time_constants)
    if not (math.isfinite(settle) and settle > 0.0):
        raise InvalidParameterError(
            f"settle_time_constants must be a finite number > 0, got {settle!r}"
        )
    u_init = None if u_initial is None else real("u_initial", u_initial)
    if u_init is not None and not math.isfinite(u_init):
        raise InvalidParameterError(f"u_initial must be finite, got {u_init!r}")

    ks, u_before, u_after = find_step(u_arr, u_init)
    if n - ks < MIN_TAIL:
        raise InvalidDataError(note("too_few_after_step", step=ks, after=n - ks, needed=MIN_TAIL))
    amplitude = u_after - u_before
    notes: list[str] = []

    baseline = float(np.mean(y_arr[: ks + 1]))
    step_time = float(t_arr[ks])
    tr = t_arr[ks:] - step_time
    yr = y_arr[ks:] - baseline
    last_change = float(yr[-1])
    noise = noise_level(yr)
    if not abs(last_change) > max(5.0 * noise, 1e-12 * max(1.0, float(np.max(np.abs(y_arr))))):
        raise InsufficientExcitationError(
            f"the output does not respond to the step: it changes by {last_change:.3g} V "
            f"(noise about {noise:.2g} V); check the rig is powered and the step is large enough"
        )

    # Tail fit: from the first 63.2 % crossing of the last-sample change to the end.
    first_cross = int(np.argmax(yr / last_change >= LEVEL_63))
    tail_start = min(first_cross, yr.size - MIN_TAIL)
    span = float(tr[-1])
    fit = fit_exponential_tail(tr[tail_start:], yr[tail_start:], span)
    change = last_change
    basis = "last sample"
    tau_fit = math.nan
    if fit is not None and fit[0] * last_change > 0.0:
        change, tau_fit = fit
        basis = "extrapolated"

    tau, t63_rel = crossing_time(tr, yr / change, noise / abs(change))
    tau_basis = "63.2% crossing"
    theta = 0.0
    if tau is not None:
        t28, _ = crossing_time(tr, yr / change, noise / abs(change), LEVEL_28)
        if t28 is not None:
            # Two points of K (1 - exp(-(t - theta)/tau)) give tau and theta.
            tau_two = 1.5 * (tau - t28)
            theta_two = tau - tau_two
            # theta = 1.5 t28 - 0.5 t63; a crossing time is uncertain by the noise
            # over the response's slope there, (noise/|change|) tau / (1 - level).
            # A dead time the noise could make is not reported (about 2 sigma).
            # The noise from the response's second differences counts a fast
            # transient's curvature as noise; before the step there is none.
            quiet = noise_level(y_arr[: ks + 1]) if ks + 1 >= 10 else noise
            rel = min(noise, quiet) / abs(change) * tau
            sigma = math.hypot(1.5 * rel / (1.0 - LEVEL_28), 0.5 * rel / (1.0 - LEVEL_63))
            if tau_two > 0.0 and theta_two > max(1e-9 * tau, 2.0 * sigma):
                theta, tau = theta_two, tau_two
    theta_seen = first_response(tr, yr * math.copysign(1.0, change), noise)
    if tau is None:
        if not math.isfinite(tau_fit):
            raise InsufficientExcitationError(
                "the output never reaches 63.2 % of its change and no exponential fits the "
                "record: record longer after the step"
            )
        tau, t63 = tau_fit, math.nan
        tau_basis = "tail fit"
        notes.append(note("no_crossing", settle=settle))
    else:
        t63 = step_time + t63_rel

    K = change / amplitude
    K_last = last_change / amplitude
    unsound = not (math.isfinite(K) and K != 0.0 and math.isfinite(tau) and tau > 0.0)
    recorded = span / tau if not unsound else math.nan
    settled = recorded >= settle
    if unsound:
        notes.insert(0, note("no_sound_fit", after=n - ks, K=K, tau=tau))
    elif not settled:
        need = settle * tau / median_dt(t_arr)
        off = 100.0 * (K_last - K) / K
        figures = {"recorded": recorded, "settle": settle, "off": off}
        said = (
            note("not_settled", need=math.ceil(need), **figures)
            if math.isfinite(need)
            else note("not_settled_far", **figures)
        )
        notes.insert(0, said)
    if not unsound:
        # What the other methods check of a final model (tau within what the
        # samples can show), then whether the response follows the record.
        notes += plausibility_warnings(K, tau, median_dt(t_arr), span)
        notes += _poor_fit(tr, yr, change, tau, theta, noise)
    if abs(amplitude) < min_step_v * (1.0 - 1e-9):  # a 1 V step read back as 0.99999...9
        notes.append(note("small_step", amplitude=abs(amplitude), minimum=min_step_v))
    if n < min_samples_v:
        notes.append(note("short_record", n=n, needed=min_samples_v))
    drift = pre_step_drift(y_arr[: ks + 1], noise)
    if abs(drift) > 0.05 * abs(change):
        share = 100.0 * abs(drift / change)
        notes.append(note("moving_before_step", drift=drift, share=share))
    for said in notes:
        warnings.warn(said, IdentificationWarning, stacklevel=2)

    return StepResponseResult(
        K=K,
        tau=tau,
        K_last_sample=K_last,
        tau_fit=tau_fit,
        final_value_basis=basis,
        tau_basis=tau_basis,
        step_index=ks,
        step_time=step_time,
        u_before=u_before,
        u_after=u_after,
        amplitude=amplitude,
        baseline=baseline,
        final_value=baseline + change,
        last_value=float(y_arr[-1]),
        t63=t63,
        direction="heating" if amplitude > 0 else "cooling",
        settled=settled,
        time_constants_recorded=recorded,
        n_samples=n,
        dt=median_dt(t_arr),
        warnings=tuple(notes),
        theta=theta,
        theta_first_response=theta_seen,
        t=t_arr,
        u=u_arr,
        y=y_arr,
    )


def _poor_fit(
    tr: npt.NDArray[np.float64],
    yr: npt.NDArray[np.float64],
    change: float,
    tau: float,
    theta: float,
    noise: float,
) -> list[str]:
    """The warning when the identified response misses the record (empty when it fits).

    A first-order response that the method's figures describe follows the
    record to within its noise; one that misses it by more than three noise
    deviations and a tenth of the change (a few samples of noise, a record
    that is no step response) is not to be shown as the plant's model.
    """
    elapsed = np.maximum(tr - theta, 0.0)
    model = change * -np.expm1(-elapsed / tau)
    # Relative to the change, so that the squares of huge readings do not overflow.
    rel = float(np.sqrt(np.mean(((yr - model) / change) ** 2)))
    if rel <= max(3.0 * noise / abs(change), 0.1):
        return []
    rms = rel * abs(change)
    if rel >= 1e6:
        return [note("poor_fit_far", rms=rms)]
    return [note("poor_fit", rms=rms, share=100.0 * rel)]
