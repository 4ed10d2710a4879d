"""The tuning table of a run: each rule's gains from its identified model, predicted and measured.

From a run's identified first-order-plus-dead-time model (the best of its
methods' final estimates: trusted before valid, ``oe`` and ``lsm`` — which
find the dead time — before the others), :func:`tuning_table` gives every
rule and form of :mod:`thermolab.control.tuning` with its ``Kp``, ``Ti``,
``Td``, the predicted closed-loop step (:func:`thermolab.control.predict_closed_loop`)
and its overshoot, settling time and IAE. :func:`closed_loop_figures` gives a
closed-loop run's measured figures beside the prediction of the model its
gains came from, with one function (:func:`thermolab.control.step_metrics`)
for both.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from thermolab.control import (
    FOPDT,
    PARAMETERS,
    RULE_FORMS,
    RULES,
    SPEED_RULES,
    LoopWord,
    PIDGains,
    predict_closed_loop,
    predict_record_step,
    rest_word,
    settling_word,
    step_metrics,
    tune,
    word_of,
)
from thermolab.errors import InvalidDataError, InvalidParameterError

__all__ = ["MODEL_PREFERENCE", "closed_loop_figures", "run_model", "tuning_table"]

#: Which method's model a table starts from, first found first (trusted ones first).
MODEL_PREFERENCE: tuple[str, ...] = ("oe", "lsm", "srm", "wlsm", "malsm", "blockls")
#: Points of a predicted response sent to a page (the figures use every sample).
_POINTS = 400


def run_model(results: Mapping[str, Any], method: str | None = None) -> tuple[str, FOPDT, bool]:
    """The FOPDT model of a run's results: ``(method, model, trusted)``.

    Raises
    ------
    InvalidParameterError
        If the run has no valid first-order model (or not from ``method``).
    """
    candidates: list[tuple[int, int, str, FOPDT, bool]] = []
    for rank, name in enumerate(MODEL_PREFERENCE):
        if method is not None and name != method:
            continue
        latest = (results.get(name) or {}).get("latest") or {}
        K, tau = latest.get("K"), latest.get("tau")
        if not latest.get("valid") or K is None or tau is None:
            continue
        extras = latest.get("extras") or {}
        theta = extras.get("theta", latest.get("theta")) or 0.0
        try:
            model = FOPDT(float(K), float(tau), float(theta))
        except InvalidParameterError:
            continue
        trusted = bool(extras.get("trusted", True))
        candidates.append((0 if trusted else 1, rank, name, model, trusted))
    if not candidates:
        which = f"method {method!r}" if method else "any method"
        raise InvalidParameterError(
            f"the run has no valid first-order model from {which}; identify the rig first "
            "(a step with SRM, LSM or OE)"
        )
    _, _, name, model, trusted = min(candidates, key=lambda c: (c[0], c[1]))
    return name, model, trusted


def _thin(values: np.ndarray) -> list[float | None]:
    step = max(1, math.ceil(len(values) / _POINTS))
    return [float(v) if math.isfinite(v) else None for v in values[::step]]


def tuning_table(
    model: FOPDT,
    *,
    dt: float,
    y0: float,
    u0: float,
    setpoint: float,
    u_limits: tuple[float, float],
    tau_c: float | None = None,
) -> dict[str, Any]:
    """Every rule and form tuned from ``model``, with its predicted step from ``(u0, y0)``.

    ``tau_c`` is the closed-loop speed of ``imc`` and ``simc`` (default: each
    rule's own). A rule that cannot tune the model (``zn``/``cc`` without dead
    time, gains out of range) gives its row an ``error`` instead.
    """
    horizon = 6.0 * (model.tau + model.theta) + 10.0 * dt
    samples = int(min(20_000, max(50, math.ceil(horizon / dt))))
    rows: list[dict[str, Any]] = []
    for rule in RULES:
        for form in RULE_FORMS[rule]:
            row: dict[str, Any] = {"rule": rule, "form": form}
            try:
                tuned = tune(model, rule, form=form, tau_c=tau_c if rule in SPEED_RULES else None)
                response = predict_closed_loop(
                    model, tuned.gains, dt=dt, samples=samples, setpoint=setpoint,
                    y0=y0, u0=u0, u_limits=u_limits,
                )  # fmt: skip
            except InvalidParameterError as exc:
                # The English for the command line and the API; the code for a page's language.
                word = word_of(exc)
                rows.append({**row, "error": str(exc), "why": word and word.to_dict()})
                continue
            rows.append(
                {
                    **row,
                    "tauC": tuned.tau_c,
                    **tuned.gains.to_dict(),
                    "predicted": response.metrics.to_dict(),
                    "response": {
                        "t": _thin(response.t),
                        "y": _thin(response.y),
                        "u": _thin(response.u),
                    },
                }
            )
    return {
        "model": model.to_dict(),
        "dt": dt,
        "y0": y0,
        "u0": u0,
        "setpoint": setpoint,
        "samples": samples,
        "rows": rows,
    }


def closed_loop_figures(
    samples: Mapping[str, Any],
    dt: float,
    control: Mapping[str, Any],
    u_limits: tuple[float, float],
    u_rest: float,
) -> dict[str, Any]:
    """A closed-loop run's measured step figures beside its model's prediction.

    ``samples`` are the run's channels by name (``t``, ``y``, ``u``, ``r``);
    ``control`` the run's control request (its starting gains, ``model`` and the
    pair it controlled: a further pair's columns stand for ``u`` and ``y``).
    The prediction is :func:`thermolab.control.predict_record_step`'s, as
    ``thermolab run``'s: from the record's operating point just before the
    step, with the gains the run started with; a run that starts in AUTO
    steps at its first sample, from rest at ``u_rest`` (the rig's safe input)
    and its first output.
    """
    t = np.asarray(samples.get("t") or [], dtype=np.float64)
    # The loop's pair: the run's own u and y, or a further pair's columns (a kit's q2, t2).
    heater, sensor = control.get("heater") or "u", control.get("sensor") or "y"
    y = np.asarray(samples.get(sensor) or [], dtype=np.float64)
    u = np.asarray(samples.get(heater) or [], dtype=np.float64)
    r_values = samples.get("r")
    out: dict[str, Any] = {
        "measured": None, "predicted": None, "note": None, "notes": [], "model": None,
    }  # fmt: skip

    def noted(*words: LoopWord | None) -> dict[str, Any]:
        # ``note`` in English (the command line's words), ``notes`` by code for a page.
        said = [w for w in words if w is not None]
        out["note"] = "; ".join(w.text for w in said) or None
        out["notes"] = [w.to_dict() for w in said]
        return out

    if r_values is None or t.size < 3:
        return noted(LoopWord.of("no_setpoint_recorded"))
    r = np.asarray([math.nan if v is None else v for v in r_values], dtype=np.float64)
    try:
        measured = step_metrics(t, r, y)
    except InvalidDataError as exc:
        # The record's faults step_metrics declares (their words, by code), else its English.
        for declared in (LoopWord.of("no_measured_step"), LoopWord.of("record_not_finite")):
            if str(exc) == declared.text:
                return noted(declared)
        out["note"] = str(exc)
        return out
    out["measured"] = measured.to_dict()
    model = control.get("model")
    if model is None:
        return noted(LoopWord.of("no_model"))
    fopdt = FOPDT(*(float(x) for x in model))
    out["model"] = fopdt.to_dict()
    n_filter = control.get("derivative_filter") or PARAMETERS["derivative_filter"].default
    # The command line's figures come from the same function: one operating point rule.
    _, predicted = predict_record_step(
        fopdt,
        PIDGains(control["kp"], control["ti"], control.get("td") or 0.0),
        t,
        r,
        y,
        u,
        dt=dt,
        u_rest=u_rest,
        u_limits=u_limits,
        derivative_filter=float(n_filter),
    )
    out["predicted"] = predicted.metrics.to_dict()
    out["response"] = {"t": _thin(predicted.t), "y": _thin(predicted.y)}
    return noted(rest_word(fopdt, measured, t, y), settling_word(measured, predicted.metrics))
