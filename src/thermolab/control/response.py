"""The closed loop predicted from an FOPDT model, and step metrics of any closed-loop record.

:func:`predict_closed_loop` runs the same :class:`~thermolab.control.pid.PID`
the runner drives against the model, sampled exactly as the runner samples a
rig: read ``y(k)``, compute ``u(k)``, hold it until ``k + 1``. The model is
discretised exactly for a zero-order-hold input, the dead time included even
when it is not a whole number of periods (the held input switches inside a
period; the two parts are integrated in closed form).

:func:`step_metrics` measures overshoot, 2 % settling time and IAE after a
set-point step, the same way for the prediction and for a measured record,
so the two can be shown side by side. :func:`predict_record_step` does both
for a measured closed-loop record (the command line's and the lab's figures):
the record's step measured, and the model's prediction of it from the
record's own operating point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.control.pid import PID, PIDGains
from thermolab.control.tuning import as_fopdt
from thermolab.control.words import LoopWord
from thermolab.errors import InvalidDataError, InvalidParameterError
from thermolab.jsonsafe import finite_or_none

__all__ = [
    "ClosedLoopResponse",
    "StepMetrics",
    "predict_closed_loop",
    "predict_record_step",
    "rest_warning",
    "rest_word",
    "settling_warning",
    "settling_word",
    "step_metrics",
]

_FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class StepMetrics:
    """How a closed loop answered a set-point step.

    Attributes
    ----------
    overshoot : float
        Peak beyond the new set point, in percent of the step (>= 0).
    settling_time : float
        Seconds from the step until the output stays within ``band`` of the
        step around the set point; NaN if it never does within the record.
    iae : float
        Integral of ``|r - y|`` from the step on (output unit · s).
    step_time : float
        When the step happened (s).
    step : float
        The set-point change (output unit).
    band : float
        The settling band as a fraction of the step (0.02).
    """

    overshoot: float
    settling_time: float
    iae: float
    step_time: float
    step: float
    band: float

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary (NaN as ``None``)."""
        return {
            "overshoot": finite_or_none(self.overshoot),
            "settling_time": finite_or_none(self.settling_time),
            "iae": finite_or_none(self.iae),
            "step_time": self.step_time,
            "step": self.step,
            "band": self.band,
        }


def step_metrics(
    t: npt.ArrayLike, r: npt.ArrayLike, y: npt.ArrayLike, *, band: float = 0.02
) -> StepMetrics:
    """Overshoot, settling time and IAE after the last set-point step of a record.

    The step is the last change of ``r``; when ``r`` never changes, the run
    started in closed loop and the step is from ``y[0]`` to ``r`` at the start.

    Parameters
    ----------
    t, r, y : array_like
        Sample times, set point and output (same length).
    band : float, optional
        Settling band as a fraction of the step (default 0.02: 2 %).

    Returns
    -------
    StepMetrics

    Raises
    ------
    InvalidDataError
        If the arrays differ in length, hold NaN, or the set point never steps.

    Examples
    --------
    >>> t = np.arange(6.0)
    >>> m = step_metrics(t, [0, 1, 1, 1, 1, 1], [0, 0, 1.2, 0.99, 1.0, 1.0])
    >>> round(m.overshoot, 6), m.settling_time, round(m.iae, 6)
    (20.0, 2.0, 1.21)
    """
    ta, ra, ya = (np.asarray(a, dtype=np.float64) for a in (t, r, y))
    if not (ta.ndim == ra.ndim == ya.ndim == 1 and len(ta) == len(ra) == len(ya)):
        raise InvalidDataError("t, r and y must be one-dimensional arrays of the same length")
    if not (np.isfinite(ta).all() and np.isfinite(ra).all() and np.isfinite(ya).all()):
        raise InvalidDataError(LoopWord.of("record_not_finite").text)
    if not (0 < band < 1):
        raise InvalidParameterError(f"band must be a fraction in (0, 1), got {band!r}")
    changes = np.flatnonzero(np.diff(ra) != 0)
    # A record that starts in closed loop steps from its first output to the set point.
    i0 = int(changes[-1]) + 1 if len(changes) else 0
    step = float(ra[i0] - (ra[i0 - 1] if i0 else ya[0]))
    if step == 0 or len(ta) - i0 < 2:
        raise InvalidDataError(LoopWord.of("no_measured_step").text)
    target = float(ra[-1])
    direction = math.copysign(1.0, step)
    after_t, after_y = ta[i0:], ya[i0:]
    overshoot = max(0.0, float(np.max(direction * (after_y - target))) / abs(step) * 100.0)
    outside = np.flatnonzero(np.abs(after_y - target) > band * abs(step))
    if len(outside) == 0:
        settling = 0.0
    elif outside[-1] == len(after_y) - 1:
        settling = math.nan
    else:
        settling = float(after_t[outside[-1] + 1] - after_t[0])
    # Rectangle rule on the sample grid: y(k) is held for the period, as the runner holds u.
    widths = np.diff(after_t, append=2 * after_t[-1] - after_t[-2])
    iae = float(np.sum(np.abs(ra[i0:] - after_y) * widths))
    return StepMetrics(overshoot, settling, iae, float(after_t[0]), step, band)


@dataclass(frozen=True, eq=False)
class ClosedLoopResponse:
    """A predicted closed-loop run: ``t``, set point ``r``, output ``y``, input ``u``.

    Attributes
    ----------
    t, r, y, u : numpy.ndarray
    metrics : StepMetrics
        :func:`step_metrics` of the response.
    """

    t: _FloatArray
    r: _FloatArray
    y: _FloatArray
    u: _FloatArray
    metrics: StepMetrics

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary."""
        return {
            "t": self.t.tolist(),
            "r": self.r.tolist(),
            "y": self.y.tolist(),
            "u": self.u.tolist(),
            "metrics": self.metrics.to_dict(),
        }


def predict_closed_loop(
    model: Any,
    gains: PIDGains,
    *,
    dt: float,
    samples: int,
    setpoint: float,
    step_at: float = 0.0,
    y0: float = 0.0,
    u0: float = 0.0,
    u_limits: tuple[float, float] = (-math.inf, math.inf),
    derivative_filter: float = 10.0,
) -> ClosedLoopResponse:
    """Simulate a set-point step in the loop of a PID and an FOPDT model.

    The plant starts at rest at the operating point ``(u0, y0)`` (``y = y0 +
    K(u - u0)`` at steady state); the set point is ``y0`` before ``step_at``
    and ``setpoint`` from then on. Before the step the controller holds ``u0``
    (bumpless start, as the runner's manual-to-auto switch).

    Parameters
    ----------
    model : FOPDT, tuple or object with K, tau (and theta)
    gains : PIDGains
    dt : float
        Sample period (s).
    samples : int
        Number of samples.
    setpoint : float
        The set point after the step (output unit).
    step_at : float, optional
        Time of the step (s, default 0).
    y0, u0 : float, optional
        The operating point (default 0, 0).
    u_limits : (float, float), optional
        The input range (default: unbounded).
    derivative_filter : float, optional
        ``N`` of the PID's derivative filter.

    Returns
    -------
    ClosedLoopResponse

    Examples
    --------
    >>> from thermolab.control.tuning import tune
    >>> g = tune((1.0, 10.0, 2.0), "simc", tau_c=2.0).gains
    >>> resp = predict_closed_loop((1.0, 10.0, 2.0), g, dt=0.1, samples=600, setpoint=1.0)
    >>> round(float(resp.y[-1]), 3), resp.metrics.overshoot < 5.0
    (1.0, True)
    """
    m = as_fopdt(model)
    if not (math.isfinite(dt) and dt > 0):
        raise InvalidParameterError(f"dt must be a positive number of seconds, got {dt!r}")
    if not (isinstance(samples, int) and samples >= 2):
        raise InvalidParameterError(f"samples must be an integer >= 2, got {samples!r}")
    low, high = u_limits
    lo = low if math.isfinite(low) else -1e300
    hi = high if math.isfinite(high) else 1e300
    pid = PID(gains, lo, hi, derivative_filter=derivative_filter)
    a = math.exp(-dt / m.tau)
    whole = math.floor(m.theta / dt + 1e-12)
    eps = m.theta - whole * dt  # the part of the delay inside a period
    if eps < 1e-12 * dt:
        eps = 0.0
    # x(k+1) = a x(k) + b_old·v(k - whole - 1) + b_new·v(k - whole), v = u - u0:
    # over [k dt, k dt + eps) the delayed input is still the older value.
    b_old = m.K * (1.0 - math.exp(-eps / m.tau)) * math.exp(-(dt - eps) / m.tau)
    b_new = m.K * (1.0 - math.exp(-(dt - eps) / m.tau))
    t = np.arange(samples, dtype=np.float64) * dt
    r = np.where(t >= step_at, float(setpoint), float(y0))
    y = np.empty(samples)
    u = np.empty(samples)
    past = np.zeros(samples + whole + 2)  # v, shifted by whole + 1 (zeros before START)
    x = 0.0
    pid.track(u0, y0, y0)  # at rest: the integral holds u0
    for k in range(samples):
        y[k] = y0 + x
        if t[k] < step_at:
            pid.track(u0, float(r[k]), float(y[k]))
            u[k] = u0
        else:
            u[k] = pid.update(float(r[k]), float(y[k]), dt)
        past[k + whole + 1] = u[k] - u0
        x = a * x + b_old * past[k] + b_new * past[k + 1]
    return ClosedLoopResponse(t, r, y, u, step_metrics(t, r, y))


def predict_record_step(
    model: Any,
    gains: PIDGains,
    t: npt.ArrayLike,
    r: npt.ArrayLike,
    y: npt.ArrayLike,
    u: npt.ArrayLike,
    *,
    dt: float,
    u_rest: float,
    u_limits: tuple[float, float] = (-math.inf, math.inf),
    derivative_filter: float = 10.0,
) -> tuple[StepMetrics, ClosedLoopResponse]:
    """A closed-loop record's set-point step, measured and predicted by ``model``.

    The prediction runs the record's gains from the record's operating point
    just before its step: the input and output of the sample before it. A
    record whose loop closes at its first sample (AUTO from START) has no
    sample before the step: its input until then was ``u_rest`` (the rig's
    safe input, where every run starts), so the prediction starts at rest
    there, from the first output — not from the first *applied* input, which
    is already the controller's answer to the step (a saturated heater taken
    for the operating point would predict a box already hot).

    Parameters
    ----------
    model : FOPDT, tuple or object with K, tau (and theta)
    gains : PIDGains
        The gains the record started with.
    t, r, y, u : array_like
        The record's times, set point, output and input.
    dt : float
        Its sample period (s).
    u_rest : float
        The input before the record (the rig's safe input).
    u_limits : (float, float), optional
        The input range.
    derivative_filter : float, optional
        ``N`` of the record's derivative filter.

    Returns
    -------
    (StepMetrics, ClosedLoopResponse)
        The measured figures, and the prediction (its ``metrics`` beside them).

    Raises
    ------
    InvalidDataError
        If the record has no set-point step (:func:`step_metrics`).

    Notes
    -----
    The model starts settled at that operating point. A box still warm from
    an earlier run and closed at its first sample is cooling, which the
    prediction cannot see (it would need the box's rest output): compare
    such figures on a box at rest; :func:`rest_warning` tells when a record
    was not.

    Examples
    --------
    >>> from thermolab.control.tuning import tune
    >>> g = tune((1.0, 10.0, 2.0), "simc", tau_c=2.0).gains
    >>> run = predict_closed_loop((1.0, 10.0, 2.0), g, dt=0.1, samples=600, setpoint=1.0)
    >>> measured, predicted = predict_record_step(
    ...     (1.0, 10.0, 2.0), g, run.t, run.r, run.y, run.u, dt=0.1, u_rest=0.0)
    >>> measured.settling_time == predicted.metrics.settling_time
    True
    """
    ta, ra, ya, ua = (np.asarray(a, dtype=np.float64) for a in (t, r, y, u))
    measured = step_metrics(ta, ra, ya)
    i0 = int(np.searchsorted(ta, measured.step_time))
    before = max(i0 - 1, 0)
    predicted = predict_closed_loop(
        model,
        gains,
        dt=dt,
        samples=int(ta.size),
        setpoint=float(ra[-1]),
        step_at=measured.step_time - float(ta[0]),
        y0=float(ya[before]),
        u0=float(ua[before]) if i0 else float(u_rest),
        u_limits=u_limits,
        derivative_filter=derivative_filter,
    )
    return measured, predicted


def rest_warning(
    model: Any, measured: StepMetrics, t: npt.ArrayLike, y: npt.ArrayLike, *, limit: float = 0.1
) -> str | None:
    """Why a record's prediction may not hold: its output was moving at the step.

    During the model's dead time after the step the output cannot yet answer
    the controller: what it does then comes from before the step. A settled
    box stays put; a box away from its rest output by ``x`` drifts back at
    ``-x / tau``. The least-squares slope over that window (robust to the
    sensor's quantum) gives ``x``; beyond ``limit`` of the step (a tenth) the
    box was not settled at the operating point :func:`predict_record_step`
    starts from (still warm from an earlier run, cooling), and the prediction
    does not describe this run. ``None`` when it was, or the model's dead time
    spans fewer than 3 samples.
    """
    word = rest_word(model, measured, t, y, limit=limit)
    return None if word is None else word.text


def rest_word(
    model: Any, measured: StepMetrics, t: npt.ArrayLike, y: npt.ArrayLike, *, limit: float = 0.1
) -> LoopWord | None:
    """:func:`rest_warning` by its code and values (``output_drifted``), for a page to say."""
    m = as_fopdt(model)
    ta, ya = np.asarray(t, dtype=np.float64), np.asarray(y, dtype=np.float64)
    i0 = int(np.searchsorted(ta, measured.step_time))
    end = int(np.searchsorted(ta, measured.step_time + m.theta, side="right"))
    if end - i0 < 3:
        return None
    slope = float(np.polyfit(ta[i0:end], ya[i0:end], 1)[0])
    away = -slope * m.tau
    if abs(away) <= limit * abs(measured.step):
        return None
    return LoopWord.of("output_drifted", slope=slope, theta=m.theta, away=away)


def settling_warning(
    measured: StepMetrics, predicted: StepMetrics, *, spread: float = 0.25
) -> str | None:
    """Why two settling times may disagree: an overshoot at the edge of the settling band.

    The settling time is discontinuous in the peak: an overshoot just inside
    the band (1.7 % of the step for a 2 % band) settles when the output first
    reaches the band, one just outside (2.3 %) only after the peak has come
    back, tens of seconds later. A record and its prediction with peaks on
    either side of the edge disagree by that jump however good the model is.
    When either overshoot lies within ``spread`` of the band (1.5 % to 2.5 %
    for 2 %), the settling times are not comparable and this says so, naming
    the figures that are: the overshoot and the IAE. ``None`` otherwise.

    Examples
    --------
    >>> near = StepMetrics(1.7, 98.0, 1294.0, 0.0, 24.0, 0.02)
    >>> far = StepMetrics(3.4, 139.0, 1250.0, 0.0, 24.0, 0.02)
    >>> settling_warning(far, far) is None
    True
    >>> print(settling_warning(near, far))  # doctest: +NORMALIZE_WHITESPACE
    the overshoot (1.7 % measured, 3.4 % predicted) is near the 2 % settling band, where the
    settling time jumps between reaching the band and leaving the peak: compare the
    overshoot and the IAE instead
    """
    word = settling_word(measured, predicted, spread=spread)
    return None if word is None else word.text


def settling_word(
    measured: StepMetrics, predicted: StepMetrics, *, spread: float = 0.25
) -> LoopWord | None:
    """:func:`settling_warning` by its code and values (``settling_near_band``), for a page."""
    edge = measured.band * 100.0
    near = [
        m.overshoot
        for m in (measured, predicted)
        if math.isfinite(m.overshoot) and abs(m.overshoot - edge) <= spread * edge
    ]
    if not near:
        return None
    return LoopWord.of(
        "settling_near_band",
        measured=measured.overshoot, predicted=predicted.overshoot, band=edge,
    )  # fmt: skip
