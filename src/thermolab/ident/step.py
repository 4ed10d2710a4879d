"""SRM: the step response method.

A first-order plant answering a step of ``ΔU`` volts moves its output by
``Δy = K ΔU`` along ``1 - exp(-t/tau)``. The method reads ``K`` from the final
value and ``tau`` as the time the output takes to cover 63.2 % of its change.
:func:`step_response` finds the step, the baseline and the final value in the
record itself and reports two gains: the paper's (the last sample of a finite
record) and a settled estimate extrapolated from the tail of the response.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares, minimize_scalar

from thermolab.errors import InsufficientExcitationError, InvalidDataError, InvalidParameterError

from ._validation import as_record, check_time, integer, real
from .models import FirstOrderModel

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["IdentificationWarning", "StepResponseResult", "step_response"]

FloatArray = npt.NDArray[np.float64]

#: The 63.2 % level of the method, exactly ``1 - 1/e``: an exponential reaches it at t = tau.
LEVEL_63 = -math.expm1(-1.0)
#: The 28.3 % level, ``1 - exp(-1/3)``: a first-order lag plus dead time reaches it
#: at ``theta + tau/3`` (and 63.2 % at ``theta + tau``), so the two give both.
LEVEL_28 = -math.expm1(-1.0 / 3.0)
# Input changes smaller than this fraction of the largest one are noise, not another step.
_OTHER_STEP_FRACTION = 0.1
# Samples the tail fit needs at least (three parameters and something to spare).
_MIN_TAIL = 6
# Tail samples the search for the time constant looks at (the final polish uses all).
_SEARCH_POINTS = 4096
# Tail samples the final fit uses at most, evenly spread (plenty to average noise).
_POLISH_POINTS = 50_000


class IdentificationWarning(UserWarning):
    """A result was computed but is less trustworthy than usual.

    Raised as a warning (never an exception) by the identification methods: a
    record that has not settled, a step under 1 V, too few samples. The same
    text is kept in the result's ``warnings``, so a program that silences
    warnings can still show them.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn("small step", IdentificationWarning, stacklevel=1)
    >>> caught[0].category.__name__
    'IdentificationWarning'
    """


@dataclass(frozen=True)
class StepResponseResult:
    """What the step response method found.

    Attributes
    ----------
    K : float
        Gain from the settled change of the output (``final_value_basis`` says how
        it was obtained): ``(final_value - baseline) / amplitude``.
    tau : float
        Time constant in seconds: the time from the step to the 63.2 % (``1 - 1/e``)
        crossing of the settled change, interpolated between samples.
    K_last_sample : float
        The paper's gain: ``(y[-1] - baseline) / amplitude``, the last sample taken as
        the final value.
    tau_fit : float
        Time constant of the exponential fitted to the tail (NaN if there was no fit).
    final_value_basis : str
        ``"extrapolated"`` (from the tail fit) or ``"last sample"`` (no usable fit).
    tau_basis : str
        ``"63.2% crossing"`` or ``"tail fit"`` (the record ends before the crossing).
    step_index : int
        First sample recorded with the new input.
    step_time : float
        Time of that sample (seconds); ``tau`` is counted from it.
    u_before, u_after : float
        Input levels before and after the step (volts).
    amplitude : float
        ``u_after - u_before``; negative for a cooling step.
    baseline : float
        Output before the step: the mean of the samples up to the step sample.
    final_value : float
        Settled output, ``baseline + K amplitude``.
    last_value : float
        The last output sample.
    t63 : float
        Time of the 63.2 % crossing (NaN when ``tau_basis`` is ``"tail fit"``).
    direction : {"heating", "cooling"}
        The sign of the step.
    settled : bool
        True when the record lasts at least ``settle_time_constants`` time constants
        after the step.
    time_constants_recorded : float
        Record length after the step, in time constants.
    n_samples : int
        Samples in the record.
    dt : float
        Median sample period (seconds).
    warnings : tuple of str
        Everything that makes the figures less trustworthy (also emitted as
        :class:`~thermolab.ident.IdentificationWarning`).
    theta : float
        Dead time in seconds: first order plus dead time fitted through the
        28.3 % and 63.2 % crossings (``t28 = theta + tau/3``, ``t63 = theta +
        tau``); ``tau`` is then ``t63 - theta``. 0 when the two agree with no delay,
        or when the delay found is within what the noise could make (two standard
        deviations of the two-point estimate).
    theta_first_response : float
        Time from the step to the last sample before the output first leaves the
        noise band (four noise deviations) for good: the dead time as seen
        directly, to a sample (NaN when not found).

    Notes
    -----
    The record arrays are kept for :meth:`plot` but are not part of the result's
    value (equality and ``repr`` ignore them).
    """

    K: float
    tau: float
    K_last_sample: float
    tau_fit: float
    final_value_basis: str
    tau_basis: str
    step_index: int
    step_time: float
    u_before: float
    u_after: float
    amplitude: float
    baseline: float
    final_value: float
    last_value: float
    t63: float
    direction: Literal["heating", "cooling"]
    settled: bool
    time_constants_recorded: float
    n_samples: int
    dt: float
    warnings: tuple[str, ...] = ()
    theta: float = 0.0
    theta_first_response: float = math.nan
    t: FloatArray = field(default_factory=lambda: np.empty(0), repr=False, compare=False)
    u: FloatArray = field(default_factory=lambda: np.empty(0), repr=False, compare=False)
    y: FloatArray = field(default_factory=lambda: np.empty(0), repr=False, compare=False)

    @property
    def model(self) -> FirstOrderModel:
        """The identified model ``K exp(-theta s) / (tau s + 1)`` (settled gain)."""
        return FirstOrderModel(self.K, self.tau, theta=self.theta)

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """A JSON-safe summary (NaN and inf become ``None``).

        Parameters
        ----------
        arrays : bool, optional
            Also include the record, ``t``, ``u`` and ``y``. Default False.

        Returns
        -------
        dict
            ``method`` (``"srm"``), every scalar attribute and ``warnings`` (a list).

        Examples
        --------
        >>> import numpy as np
        >>> from thermolab.simulation import simulate_first_order
        >>> t = np.arange(3000.0)
        >>> u = np.where(t >= 1, 10.0, 0.0)
        >>> d = step_response(t, u, simulate_first_order(u, 0.14, 250.0, 1.0)).to_dict()
        >>> d["method"], round(d["K"], 6), round(d["tau"], 6), d["warnings"]
        ('srm', 0.14, 250.0, [])
        """
        out: dict[str, Any] = {"method": "srm"}
        for name in (
            "K",
            "tau",
            "K_last_sample",
            "tau_fit",
            "final_value_basis",
            "tau_basis",
            "step_index",
            "step_time",
            "u_before",
            "u_after",
            "amplitude",
            "baseline",
            "final_value",
            "last_value",
            "t63",
            "direction",
            "settled",
            "time_constants_recorded",
            "n_samples",
            "dt",
            "theta",
            "theta_first_response",
        ):
            value = getattr(self, name)
            if isinstance(value, float) and not math.isfinite(value):
                value = None
            out[name] = value
        out["warnings"] = list(self.warnings)
        if arrays:
            for name in ("t", "u", "y"):
                out[name] = [float(v) for v in getattr(self, name)]
        return out

    def plot(self, *, title: str | None = None) -> Figure:
        """The record, the identified response and the 63.2 % point (the paper's Fig. 5).

        Parameters
        ----------
        title : str, optional
            Figure title; default gives ``K``, ``tau`` and the step.

        Returns
        -------
        matplotlib.figure.Figure
            Output (top) and input (bottom) against time; not attached to pyplot
            (save it with ``fig.savefig(path)``).

        Raises
        ------
        ImportError
            If matplotlib is not installed (``pip install 'thermolab[plot]'``).
        """
        from ._plotting import _figure

        fig = _figure()
        ax_y, ax_u = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1))
        ax_y.plot(self.t, self.y, color="k", linewidth=1, label="measured")
        after = self.t >= self.step_time + self.theta
        change = self.final_value - self.baseline
        elapsed = self.t[after] - self.step_time - self.theta
        model = self.baseline + change * -np.expm1(-elapsed / self.tau)
        ax_y.plot(self.t[after], model, color="tab:red", linewidth=1, label="first-order model")
        ax_y.axhline(self.baseline, color="0.5", linewidth=0.8, linestyle=":")
        ax_y.axhline(
            self.final_value,
            color="tab:red",
            linewidth=0.8,
            linestyle="--",
            label=f"final value ({self.final_value_basis})",
        )
        if math.isfinite(self.t63):
            ax_y.plot(
                [self.t63],
                [self.baseline + LEVEL_63 * change],
                "o",
                color="tab:blue",
                label="63.2 % of the change",
            )
        ax_u.step(self.t, self.u, where="post", color="tab:blue", linewidth=1)
        ax_y.set_ylabel("y (V)")
        ax_u.set_ylabel("u (V)")
        ax_u.set_xlabel("time (s)")
        for ax in (ax_y, ax_u):
            ax.grid(True, alpha=0.3)
        ax_y.legend(loc="best")
        fig.suptitle(
            title
            or f"step response ({self.direction}, {self.u_before:.4g} → {self.u_after:.4g} V): "
            f"K = {self.K:.6g}, tau = {self.tau:.6g} s"
        )
        return fig


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
        is shorter than ``min_samples``, the output was moving before the step, or
        the record ends before the 63.2 % crossing. Each is also in ``warnings``.

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

    ks, u_before, u_after = _find_step(u_arr, u_init)
    if n - ks < _MIN_TAIL:
        raise InvalidDataError(
            f"too few samples after the step: the step is at sample {ks} and only {n - ks} "
            f"samples follow; the step method needs at least {_MIN_TAIL} (the paper records 2000)"
        )
    amplitude = u_after - u_before
    notes: list[str] = []

    baseline = float(np.mean(y_arr[: ks + 1]))
    step_time = float(t_arr[ks])
    tr = t_arr[ks:] - step_time
    yr = y_arr[ks:] - baseline
    last_change = float(yr[-1])
    noise = _noise_level(yr)
    if not abs(last_change) > max(5.0 * noise, 1e-12 * max(1.0, float(np.max(np.abs(y_arr))))):
        raise InsufficientExcitationError(
            f"the output does not respond to the step: it changes by {last_change:.3g} V "
            f"(noise about {noise:.2g} V); check the rig is powered and the step is large enough"
        )

    # Tail fit: from the first 63.2 % crossing of the last-sample change to the end.
    first_cross = int(np.argmax(yr / last_change >= LEVEL_63))
    tail_start = min(first_cross, yr.size - _MIN_TAIL)
    span = float(tr[-1])
    fit = _fit_exponential_tail(tr[tail_start:], yr[tail_start:], span)
    change = last_change
    basis = "last sample"
    tau_fit = math.nan
    if fit is not None and fit[0] * last_change > 0.0:
        change, tau_fit = fit
        basis = "extrapolated"

    tau, t63_rel = _crossing_time(tr, yr / change, noise / abs(change))
    tau_basis = "63.2% crossing"
    theta = 0.0
    if tau is not None:
        t28, _ = _crossing_time(tr, yr / change, noise / abs(change), LEVEL_28)
        if t28 is not None:
            # Two points of K (1 - exp(-(t - theta)/tau)) give tau and theta.
            tau_two = 1.5 * (tau - t28)
            theta_two = tau - tau_two
            # theta = 1.5 t28 - 0.5 t63; a crossing time is uncertain by the noise
            # over the response's slope there, (noise/|change|) tau / (1 - level).
            # A dead time the noise could make is not reported (about 2 sigma).
            # The noise from the response's second differences counts a fast
            # transient's curvature as noise; before the step there is none.
            quiet = _noise_level(y_arr[: ks + 1]) if ks + 1 >= 10 else noise
            rel = min(noise, quiet) / abs(change) * tau
            sigma = math.hypot(1.5 * rel / (1.0 - LEVEL_28), 0.5 * rel / (1.0 - LEVEL_63))
            if tau_two > 0.0 and theta_two > max(1e-9 * tau, 2.0 * sigma):
                theta, tau = theta_two, tau_two
    theta_seen = _first_response(tr, yr * math.copysign(1.0, change), noise)
    if tau is None:
        if not math.isfinite(tau_fit):
            raise InsufficientExcitationError(
                "the output never reaches 63.2 % of its change and no exponential fits the "
                "record: record longer after the step"
            )
        tau, t63 = tau_fit, math.nan
        tau_basis = "tail fit"
        notes.append(
            "no 63.2% crossing: the record ends before the output covers 63.2 % of its "
            "extrapolated change, so tau is the fitted time constant; record at least "
            f"{settle:g} time constants after the step"
        )
    else:
        t63 = step_time + t63_rel

    recorded = span / tau
    settled = recorded >= settle
    K = change / amplitude
    K_last = last_change / amplitude
    if not settled:
        notes.insert(
            0,
            f"not settled: the record lasts {recorded:.2f} time constants after the step "
            f"(needs {settle:g}); the last sample is {100.0 * (K_last - K) / K:+.2f} % off the "
            f"extrapolated gain; record at least {math.ceil(settle * tau / _median_dt(t_arr))} "
            "samples after the step",
        )
    if abs(amplitude) < min_step_v * (1.0 - 1e-9):  # a 1 V step read back as 0.99999...9
        notes.append(
            f"small step: the input changes by {abs(amplitude):.3g} V, under {min_step_v:g} V, "
            "so noise weighs more on the result; use a step of at least "
            f"{min_step_v:g} V"
        )
    if n < min_samples_v:
        notes.append(
            f"short record: {n} samples, fewer than the {min_samples_v} the paper asks for "
            "(the transient and the settled output must both be recorded)"
        )
    drift = _pre_step_drift(y_arr[: ks + 1], noise)
    if abs(drift) > 0.05 * abs(change):
        notes.append(
            f"moving before the step: the output changed by {drift:.3g} V before the step "
            f"({100.0 * abs(drift / change):.0f} % of the response), so the baseline is "
            "uncertain; start from rest (a cold rig)"
        )
    for note in notes:
        warnings.warn(note, IdentificationWarning, stacklevel=2)

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
        dt=_median_dt(t_arr),
        warnings=tuple(notes),
        theta=theta,
        theta_first_response=theta_seen,
        t=t_arr,
        u=u_arr,
        y=y_arr,
    )


def _find_step(u: FloatArray, u_initial: float | None) -> tuple[int, float, float]:
    """Index of the first sample with the new input, and the levels either side."""
    ext = u if u_initial is None else np.concatenate([[u_initial], u])
    jumps = np.abs(np.diff(ext))
    scale = max(1.0, float(np.max(np.abs(ext))))
    if jumps.size == 0 or float(jumps.max()) <= 1e-12 * scale:
        hint = (
            ""
            if u_initial is not None
            else (
                "; if the step happened at the first sample, give u_initial (the input before it)"
            )
        )
        raise InsufficientExcitationError(
            f"no step: the input stays at {float(ext[0]):.6g} V for the whole record, so the "
            f"output shows no step response{hint}"
        )
    j = int(np.argmax(jumps))
    others = np.flatnonzero(jumps > _OTHER_STEP_FRACTION * jumps[j])
    others = others[others != j]
    if others.size:
        offset = 0 if u_initial is None else 1
        where = ", ".join(str(int(i) + 1 - offset) for i in others[:5])
        raise InvalidDataError(
            f"the input changes more than once (also at sample {where}"
            f"{', ...' if others.size > 5 else ''}; the main step is at sample "
            f"{j + 1 - offset}): the step method needs a single step; cut the record to one "
            "step or use a least-squares method"
        )
    ks = j + 1 - (0 if u_initial is None else 1)
    return ks, float(np.mean(ext[: j + 1])), float(np.mean(ext[j + 1 :]))


def _noise_level(x: FloatArray) -> float:
    """Robust noise standard deviation from the sample-to-sample differences."""
    if x.size < 3:
        return 0.0
    d = np.diff(x)
    # MAD of the differences of the differences ignores a smooth trend; the
    # second difference of white noise has variance 6 sigma^2.
    dd = np.diff(d)
    return float(np.median(np.abs(dd - np.median(dd))) / 0.6745 / math.sqrt(6.0))


def _pre_step_drift(y_pre: FloatArray, noise: float) -> float:
    """Change of the output across the samples before the step (0 when too few)."""
    if y_pre.size < 10:
        return 0.0
    m = max(1, y_pre.size // 5)
    drift = float(np.mean(y_pre[-m:]) - np.mean(y_pre[:m]))
    return drift if abs(drift) > 3.0 * noise / math.sqrt(m) else 0.0


def _median_dt(t: FloatArray) -> float:
    return float(np.median(np.diff(t))) if t.size > 1 else math.nan


def _fit_exponential_tail(
    tr: FloatArray, yr: FloatArray, span: float
) -> tuple[float, float] | None:
    """Fit ``d - c exp(-(t - t0)/tau)``; return ``(d, tau)`` or None if it cannot be done."""
    if tr.size < _MIN_TAIL:
        return None
    x = tr - tr[0]
    width = float(x[-1])
    if width <= 0.0:
        return None
    step = float(np.min(np.diff(tr)))
    # tau far below a sample or far beyond the record is not determined by the data.
    lo, hi = math.log(step / 20.0), math.log(20.0 * max(span, width))

    # The search for tau looks at a few thousand samples of the tail and the final
    # fit at up to 50 000, so a long record costs little more than a short one.
    xs, ys = _spread(x, _SEARCH_POINTS), _spread(yr, _SEARCH_POINTS)

    def sse(log_tau: float) -> float:
        return _separable_fit(xs, ys, log_tau)[0]

    grid = np.linspace(lo, hi, 64)
    costs = np.array([sse(g) for g in grid])
    i = int(np.argmin(costs))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best = minimize_scalar(sse, bounds=(a, b), method="bounded")
    log_tau = float(best.x) if best.fun <= costs[i] else float(grid[i])
    # Brent's tolerance is relative to log(tau); Levenberg-Marquardt on all three
    # parameters polishes the solution to rounding, which the 63.2 % crossing needs.
    xp, yp = _spread(x, _POLISH_POINTS), _spread(yr, _POLISH_POINTS)
    cost, d0, c0 = _separable_fit(xp, yp, log_tau)

    def residual(p: FloatArray) -> FloatArray:
        r: FloatArray = p[0] - p[1] * np.exp(-xp * math.exp(-p[2])) - yp
        return r

    def jacobian(p: FloatArray) -> FloatArray:
        rate = math.exp(-p[2])
        e = np.exp(-xp * rate)
        return np.column_stack([np.ones_like(xp), -e, -p[1] * e * xp * rate])

    polished = least_squares(
        residual,
        np.array([d0, c0, log_tau]),
        jac=jacobian,
        method="lm",
        xtol=1e-15,
        ftol=1e-15,
        gtol=1e-15,
    )
    if polished.success and 2.0 * polished.cost <= cost and lo <= polished.x[2] < hi:
        d, log_tau = float(polished.x[0]), float(polished.x[2])
    else:
        d = d0
    if not math.isfinite(d) or log_tau >= hi - 1e-9:
        return None
    return d, math.exp(log_tau)


def _spread(a: FloatArray, m: int) -> FloatArray:
    """At most ``m`` samples of ``a``, evenly spread, first and last included."""
    if a.size <= m:
        return a
    return a[np.linspace(0, a.size - 1, m).astype(np.intp)]


def _separable_fit(x: FloatArray, y: FloatArray, log_tau: float) -> tuple[float, float, float]:
    """Least squares of ``y ~ d - c exp(-x/tau)`` for a fixed tau: ``(sse, d, c)``."""
    e = np.exp(-x * math.exp(-log_tau))
    e_mean, y_mean = float(e.mean()), float(y.mean())
    ec, yc = e - e_mean, y - y_mean
    see = float(ec @ ec)
    sey = float(ec @ yc)
    syy = float(yc @ yc)
    if see <= 0.0:
        return syy, y_mean, 0.0
    slope = sey / see
    return max(syy - slope * sey, 0.0), y_mean - slope * e_mean, -slope


def _first_response(tr: FloatArray, yr: FloatArray, noise: float) -> float:
    """Time of the last sample before ``yr`` (rising) leaves the noise band for good."""
    band = max(4.0 * noise, 1e-12 * max(1.0, float(np.max(np.abs(yr)))))
    outside = yr > band
    inside = np.flatnonzero(~outside)
    if outside.all():
        return 0.0
    if inside.size == 0 or inside[-1] == yr.size - 1:
        return math.nan
    return float(tr[int(inside[-1])])


def _crossing_time(
    tr: FloatArray, z: FloatArray, z_noise: float, level: float = LEVEL_63
) -> tuple[float | None, float]:
    """Time (from the step) where the normalised response ``z`` reaches ``level`` (1 - 1/e).

    ``log(1 - z)`` is linear in time for an exponential, so the crossing is where a
    straight line through ``log(1 - z)`` meets ``-1``. Noise-free, the line goes
    through the two samples around the crossing (exact). With noise ``z_noise``
    the response wanders across the level several times; the line is then
    fitted to every sample within three noise deviations of the level, which
    averages the noise out instead of taking the first (early) crossing.
    """
    side = z >= level
    changes = np.flatnonzero(side[1:] != side[:-1]) + 1
    if changes.size == 0:
        if side[0]:
            return float(tr[0]), float(tr[0])
        return None, math.nan
    first, last = int(changes[0]), int(changes[-1])
    band = min(3.0 * z_noise, 0.25)
    sel = np.abs(z - level) <= band
    sel[[first - 1, first, last - 1, last]] = True
    sel &= z < 1.0
    if np.count_nonzero(sel) > 2:
        slope, intercept = np.polyfit(tr[sel], np.log1p(-z[sel]), 1)
        if slope < 0.0:
            tc = float((math.log1p(-level) - intercept) / slope)
            if tr[first - 1] - 1e-9 <= tc <= tr[last] + 1e-9 or first == last:
                return tc, tc
    tc = 0.5 * (
        _interpolate_crossing(tr, z, first, level) + _interpolate_crossing(tr, z, last, level)
    )
    return tc, tc


def _interpolate_crossing(tr: FloatArray, z: FloatArray, j: int, level: float) -> float:
    """Crossing of ``level`` between samples j-1 and j, exact for an exponential."""
    r0, r1 = 1.0 - z[j - 1], 1.0 - z[j]
    target = 1.0 - level
    if r0 > 0.0 and r1 > 0.0 and r0 != r1:
        frac = math.log(r0 / target) / math.log(r0 / r1)
    else:
        frac = (level - z[j - 1]) / (z[j] - z[j - 1])
    return float(tr[j - 1] + frac * (tr[j] - tr[j - 1]))
