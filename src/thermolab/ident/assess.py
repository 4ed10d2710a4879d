"""Identify a whole record with one method and judge the model: one behaviour everywhere.

:func:`assess` is what ``thermolab identify`` does to a file and what the lab
does to a handed-in run: refuse a record no method can identify
(:func:`~thermolab.ident.verdict.check_identifiable`), run the registry's
batch function with the given settings, collect every warning it gives (those
it raises while it works included) and the time axis's jitter and gaps, and
judge the model on the record (:func:`~thermolab.ident.verdict.judge`): the
free-run fit, agreement with the output-error fit of the same record, the
start of a record whose input is on from its first row, convergence. Its
``trusted`` is the verdict's, not a warning-free result's (real kits fail
residual whiteness tests without being wrong; a warning-free windowed
estimate over a settled tail can be far off: :mod:`thermolab.ident.verdict`).

Examples
--------
>>> import numpy as np
>>> from thermolab.simulation import simulate_first_order
>>> t = np.arange(600.0)
>>> u = np.where(t >= 10, 5.0, 0.0)
>>> y = simulate_first_order(u, 0.5, 60.0, 1.0)
>>> a = assess("lsm", t, u, y, 1.0)
>>> a.trusted, round(a.summary["K"], 3), round(a.summary["tau"], 1)
(True, 0.5, 60.0)
"""

from __future__ import annotations

import dataclasses
import inspect
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.errors import InsufficientExcitationError, ThermoLabError

from .diagnostics import timing_warnings
from .registry import get_method
from .table_figures import table_figures
from .units import error_in_units, in_units
from .verdict import Verdict, check_identifiable, judge

__all__ = ["ON_TIME_STAMPS", "Assessment", "assess", "judge_model", "peer_estimate"]

ON_TIME_STAMPS = ("srm", "oe")
"""Methods that use the recorded time stamps (interpolated crossing; simulation at the stamps)."""


@dataclass(frozen=True)
class Assessment:
    """A method's model of a record and the verdict on it.

    Attributes
    ----------
    method : str
        The registry's name of the method.
    result : object
        The method's own result (``LSMResult``, ``Trajectory``...).
    summary : dict
        JSON-ready: ``K``, ``tau``, ``theta``, ``valid``, ``reason``,
        ``warnings`` (every one, in the order met) and the method's own
        figures; a recursive or windowed method's statistics and
        ``after_convergence``.
    verdict : Verdict
        Whether to trust the model, and why not.
    """

    method: str
    result: Any
    summary: dict[str, Any]
    verdict: Verdict

    @property
    def trusted(self) -> bool:
        """The verdict's: a model to show as right (:func:`~thermolab.ident.verdict.judge`)."""
        return self.verdict.trusted


def assess(
    method: str,
    t: npt.ArrayLike,
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    settings: Mapping[str, Any] | None = None,
    *,
    units: tuple[str, str] | None = None,
    notes: Sequence[str] = (),
    peers: dict[str, dict[str, Any]] | None = None,
) -> Assessment:
    """Identify a whole record with one method and judge the model on it.

    Parameters
    ----------
    method : str
        A registry name (``srm``, ``lsm``, ``blockls``, ``malsm``, ``wlsm``, ``oe``).
    t, u, y : array_like
        The record's time stamps (s), input and output.
    dt : float
        The sample period the method assumes (s): the record's median step.
    settings : mapping, optional
        The method's settings by name (:mod:`thermolab.ident.registry`). A
        recursive or windowed method's statistics cover the samples after
        convergence (the paper's count) unless ``last`` is given.
    units : (str, str), optional
        The input's and the output's units: every warning, reason and refusal
        then speaks of them, not of the volts the methods' own messages use
        (:func:`~thermolab.ident.units.in_units`).
    notes : sequence of str, optional
        Warnings the caller met reading the record (rows merged...), judged
        with the method's.
    peers : dict, optional
        The output-error fits of this record, shared by several methods'
        verdicts (:func:`judge_model`): pass the same dict for each.

    Returns
    -------
    Assessment

    Raises
    ------
    InvalidDataError, InsufficientExcitationError
        A record no method can identify, or no first-order model from this
        one (never a null model): one line saying why.
    InvalidParameterError
        An unknown method or a setting it does not take.
    """
    ta, ua, ya = (np.asarray(a, dtype=np.float64) for a in (t, u, y))
    try:
        given = dict(settings or {})
        assessment = _assess(method, ta, ua, ya, float(dt), given, units, notes, peers)
    except ThermoLabError as exc:
        raise (exc if units is None else error_in_units(exc, *units)) from None
    return assessment if units is None else _in_units(assessment, *units)


def _assess(
    method: str,
    ta: npt.NDArray[np.float64],
    ua: npt.NDArray[np.float64],
    ya: npt.NDArray[np.float64],
    dt: float,
    given: dict[str, Any],
    units: tuple[str, str] | None,
    notes: Sequence[str],
    peers: dict[str, dict[str, Any]] | None,
) -> Assessment:
    m = get_method(method)
    u_unit, y_unit = units or ("", "")
    check_identifiable(ua, ya, y_unit, u_unit)
    identify = {k: v for k, v in given.items() if k in m.setting_names("identify")}
    data = {"t": ta, "u": ua, "y": ya, "dt": dt}
    function = m.batch_function()
    if "t" not in m.data and "t" in inspect.signature(function).parameters:
        identify["t"] = ta  # the sample times: jitter and gaps are flagged
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = function(*(data[name] for name in m.data), **identify)
    summary = _summary(method, result, dt, given)
    if summary.get("K") is None or summary.get("tau") is None or summary.get("valid") is False:
        why = summary.get("reason") or "the estimate has no first-order meaning"
        raise InsufficientExcitationError(f"no first-order model from {method}: {why}")
    found = list(summary.get("warnings", []))
    # The same jitter and gap warnings whichever method is asked.
    for text in [*notes, *(str(w.message) for w in caught), *timing_warnings(ta)]:
        if text not in found:
            found.append(text)
    summary["warnings"] = found
    after = summary.get("after_convergence")
    verdict = judge_model(
        method,
        ta,
        ua,
        ya,
        dt,
        K=summary["K"],
        tau=summary["tau"],
        theta=summary.get("theta"),
        warnings=found,
        converged=None if after is None else bool(after.get("converged")),
        reason=summary.get("reason"),
        peers=peers,
    )
    return Assessment(method, result, summary, verdict)


def _in_units(a: Assessment, u_unit: str, y_unit: str) -> Assessment:
    """The assessment's words in the record's units (judged before: the checks read the kinds)."""

    def said(text: str) -> str:
        return in_units(text, u_unit, y_unit)

    summary = dict(a.summary)
    summary["warnings"] = [said(w) for w in summary["warnings"]]
    if isinstance(summary.get("reason"), str):
        summary["reason"] = said(summary["reason"])
    op = summary.get("operating_point")
    if isinstance(op, dict):
        summary["operating_point"] = {
            k: said(v) if k in ("reason", "start") and isinstance(v, str) else v
            for k, v in op.items()
        }
    verdict = dataclasses.replace(
        a.verdict,
        reasons=tuple(said(r) for r in a.verdict.reasons),
        notes=tuple(said(n) for n in a.verdict.notes),
    )
    return dataclasses.replace(a, summary=summary, verdict=verdict)


def _summary(method: str, result: Any, dt: float, settings: Mapping[str, Any]) -> dict[str, Any]:
    m = get_method(method)
    if "trajectory" not in m.returns:
        d: dict[str, Any] = result.to_dict()
        out = {"method": method, "dt": dt, "K": d.pop("K"), "tau": d.pop("tau")}
        d.pop("method", None)
        d.pop("dt", None)
        out.update(d)
        return out
    stats = m.defaults("statistics")
    stats.update(settings)
    stats = {k: v for k, v in stats.items() if k in m.setting_names("statistics")}
    d = result.to_dict(arrays=False, **stats)
    final = d.pop("final")
    at, latest = result.last_estimate
    if at is not None and at != result.n_samples - 1:
        # A complete record: its answer is the last estimate made, not "not yet".
        valid = latest.valid
        final = {"K": latest.K if valid else None, "tau": latest.tau if valid else None,
                 "theta": latest.theta if valid else None, "valid": valid,
                 "reason": latest.reason}  # fmt: skip
    out = {
        "method": method,
        "dt": dt,
        "K": final["K"],
        "tau": final["tau"],
        "theta": final["theta"],
        "valid": final["valid"],
        "reason": final["reason"],
        "estimate_at": at,
        "stats": d.pop("stats"),
        # The paper's count (statistics after convergence) unless the last N are asked for.
        "stats_over": "last" if settings.get("last") is not None else "after_convergence",
    }
    # The figures a table shows, by the one rule the lab's run pages use too.
    out["figures"] = table_figures(result, tol=stats.get("tol", 0.01), last=settings.get("last"))
    converged = d.pop("converged_at")
    if "tol" in stats:
        out["converged_at"] = converged
        out["tol"] = stats["tol"]
    out["last"] = stats["last"]
    d.pop("method", None)
    d.pop("dt", None)
    out.update(d)
    return out


def judge_model(
    method: str,
    t: npt.ArrayLike,
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    *,
    K: float | None,
    tau: float | None,
    theta: float | None,
    warnings: Sequence[str],
    converged: bool | None = None,
    reason: str | None = None,
    peers: dict[str, dict[str, Any]] | None = None,
) -> Verdict:
    """The verdict on a model ``method`` gave of a whole record, however it was made.

    :func:`assess` judges the batch function's model; the lab judges a run's
    live estimate at its end the same way. Every method but oe is compared
    with the output-error fit of the same record (the unbiased whole-record
    estimate, which simulates at the time stamps); a record whose input is on
    from its first row also with the fit that takes the kit at rest before it.

    Parameters
    ----------
    method : str
        The registry's name (``srm`` and ``oe`` use the time stamps).
    t, u, y : array_like
        The record.
    dt : float
        Its sample period (s).
    K, tau, theta : float or None
        The model (``None``: no model).
    warnings : sequence of str
        The method's warnings.
    converged : bool, optional
        A recursive or windowed estimate: whether it converged.
    reason : str, optional
        Why there is no model.
    peers : dict, optional
        A cache of the output-error fits for several methods of one record
        (filled here; pass the same dict for each).
    """
    ta, ua, ya = (np.asarray(a, dtype=np.float64) for a in (t, u, y))
    cache = {} if peers is None else peers
    peer = None
    if method != "oe":
        if "auto" not in cache:
            cache["auto"] = peer_estimate(ta, ua, ya, dt)
        peer = cache["auto"]
    at_rest = None
    if ua[0] != 0.0:
        # What the record would say had the kit been at rest, input off, before it.
        if "rest" not in cache:
            t0 = float(ta[0]) - dt
            rest = peer_estimate(np.r_[t0, ta], np.r_[0.0, ua], np.r_[ya[0], ya], dt, "rest")
            cache["rest"] = {**rest, "u0": float(ua[0])}
        at_rest = cache["rest"]
    return judge(
        K,
        tau,
        theta,
        warnings,
        ta,
        ua,
        ya,
        honours_time=method in ON_TIME_STAMPS,
        peer=peer,
        converged=converged,
        reason=reason,
        at_rest=at_rest,
    )


def peer_estimate(
    t: npt.ArrayLike, u: npt.ArrayLike, y: npt.ArrayLike, dt: float, start: str = "auto"
) -> dict[str, Any]:
    """The output-error fit of a record with its defaults, or no model (and why).

    ``start="rest"``: the fit that assumes the kit at rest, input off, before
    the record (:func:`~thermolab.ident.oe.output_error_at_rest`).
    """
    from .oe import output_error, output_error_at_rest

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if start == "rest":
                r = output_error_at_rest(u, y, dt, t=t)
            else:
                r = output_error(u, y, dt, t=t)
    except ThermoLabError as exc:
        return {"method": "oe", "K": None, "tau": None, "theta": None, "reason": str(exc)}
    if not r.model.valid:
        return {"method": "oe", "K": None, "tau": None, "theta": None, "reason": r.model.reason}
    return {"method": "oe", "K": r.K, "tau": r.tau, "theta": r.theta}
