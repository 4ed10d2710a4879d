"""Whether to trust a model identified from a whole record: checks that hold on real kits.

A warning-free result was the old test of trust. Real kits break two of its
rules without being wrong: the paper's 2000-sample count (a kit that has
settled after 500 samples is as well identified), and the residual whiteness
and independence tests (a real heater is higher order than a first-order model,
so no real record passes them, however good the model). And a warning-free
final estimate of a moving-window or recursive method can be far off (a window
over a settled tail fits noise). The verdict here replaces those rules with
checks that separate right from wrong on real records (the corpus in
``docs/real-records.md``):

1. **A model at all**: finite ``K`` and ``tau > 0``.
2. **No warning that makes the model wrong**: no excitation, an undetermined
   operating point, an implausible estimate, and the time axis's jitter and
   gaps for a method that assumes a fixed period (output error simulates at the
   recorded time stamps, so for it they are notes). The residual tests, the
   2000-sample count and an extrapolated final value are notes only: the next
   checks judge the model.
3. **Free-run fit**: the model, simulated at the recorded time stamps from the
   record's input (an offset and a decaying start fitted), follows the record
   (:data:`MIN_FIT` % at least) and its last third, predicted with the offset
   fitted on the first two thirds (:data:`MIN_FIT` % at least, relative to the
   record's whole swing).
4. **Agreement between methods**: ``K``, ``tau`` within :data:`AGREE_REL` and
   ``theta`` within :data:`AGREE_THETA` s of an independent estimate (the
   output-error fit of the same record) where one is given. A dead time that
   differs more is reported as uncertain.
5. **Convergence** of a recursive or windowed estimate, where it is known.

A model that fails a check is not trusted, and each failed check gives one
line saying why.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.errors import InsufficientExcitationError, InvalidDataError

from .notes import note
from .oe import simulate_fopdt_at

__all__ = [
    "AGREE_REL",
    "AGREE_THETA",
    "MIN_FIT",
    "MIN_SAMPLES",
    "NOTE_PREFIXES",
    "TIMING_PREFIXES",
    "Verdict",
    "check_identifiable",
    "free_run_fit",
    "judge",
]

FloatArray = npt.NDArray[np.float64]

MIN_FIT = 80.0
"""The least free-run fit (%) on the record and on its last third."""
AGREE_REL = 0.10
"""Relative agreement of ``K`` and ``tau`` with the independent estimate."""
AGREE_THETA = 5.0
"""Agreement of the dead time with the independent estimate, in seconds."""

MIN_SAMPLES = 20
"""The fewest samples any method is given a record with (the output-error fit's minimum)."""

NOTE_PREFIXES = ("residual test failed", "short record", "not settled", "duplicated time")
"""Warnings that are notes only: the free-run fit and the agreement judge the model."""
TIMING_PREFIXES = ("timing jitter", "gap in time")
"""Warnings about the time axis: notes for a method that simulates at the time stamps."""


@dataclass(frozen=True)
class Verdict:
    """Whether a model is trusted, and why not.

    Attributes
    ----------
    trusted : bool
        Every check passed.
    reasons : tuple of str
        One line per failed check (empty when trusted).
    notes : tuple of str
        Warnings kept as information only (they did not decide).
    fit_record, fit_holdout : float or None
        Free-run fit % on the record and on its last third.
    agreement : dict
        The independent estimate compared with (``method``, ``K``, ``tau``,
        ``theta``), or empty.
    """

    trusted: bool
    reasons: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    fit_record: float | None = None
    fit_holdout: float | None = None
    agreement: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``trusted, reasons, notes, fit_record, fit_holdout, agreement``."""
        return {
            "trusted": self.trusted,
            "reasons": list(self.reasons),
            "notes": list(self.notes),
            "fit_record": self.fit_record,
            "fit_holdout": self.fit_holdout,
            "agreement": dict(self.agreement),
        }


def check_identifiable(
    u: npt.ArrayLike, y: npt.ArrayLike, y_unit: str = "", u_unit: str = ""
) -> None:
    """Refuse, in one line, a record no method can identify a model from.

    The same refusal whichever method is asked: too few samples, an input that
    never changes, an output that never changes, and an input in % outside
    0-100 (a heater asked for more than it can give saturates: the output
    answers to 100 %, not to what was recorded).

    Raises
    ------
    InvalidDataError
        Fewer than :data:`MIN_SAMPLES` samples, or a saturated input.
    InsufficientExcitationError
        No excitation (the input never changes) or a flat output.

    Examples
    --------
    >>> check_identifiable([0.0] * 30, list(range(30)))
    Traceback (most recent call last):
    ...
    thermolab.errors.InsufficientExcitationError: no excitation: the input never changes ...
    """
    ua, ya = np.asarray(u, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if ya.size < MIN_SAMPLES:
        raise InvalidDataError(note("too_few_to_identify", n=ya.size, needed=MIN_SAMPLES))
    if np.ptp(ua) == 0.0:
        raise InsufficientExcitationError(note("input_never_changes", u=float(ua[0])))
    if u_unit == "%" and (float(np.min(ua)) < 0.0 or float(np.max(ua)) > 100.0):
        worst = float(np.max(ua)) if float(np.max(ua)) > 100.0 else float(np.min(ua))
        raise InvalidDataError(
            f"saturated input: the record asks the heater for {worst:g} % but it gives 0 to "
            "100 %, so the output answers to a clipped input; keep the input within 0-100 %"
        )
    if np.ptp(ya) == 0.0:
        unit = f" {y_unit}" if y_unit else ""
        raise InsufficientExcitationError(
            f"flat output: the output never changes (it stays at {float(ya[0]):g}{unit}) while "
            "the input does; check that the sensor is connected and the right column is read"
        )


def free_run_fit(
    t: npt.ArrayLike, u: npt.ArrayLike, y: npt.ArrayLike, K: float, tau: float, theta: float
) -> tuple[float, float]:
    """Free-run fit % of a FOPDT model on the record and on its last third.

    The model is simulated at the time stamps from rest under the first input;
    an offset and a start ``c e^{-(t - t0)/tau}`` (a record that does not start
    at rest) are fitted by linear least squares, on the whole record for the
    first figure and on its first two thirds for the second. Fit % is
    ``100 (1 - rms(error) / sd(y))``, ``sd`` over the whole record for both (a
    settled tail has almost no spread of its own).

    Examples
    --------
    >>> import numpy as np
    >>> from thermolab.ident.oe import simulate_fopdt_at
    >>> t = np.arange(600.0); u = np.where(t >= 20, 50.0, 0.0)
    >>> y = 21.0 + simulate_fopdt_at(t, u, 0.6, 140.0, 15.0)
    >>> [round(f, 6) for f in free_run_fit(t, u, y, 0.6, 140.0, 15.0)]
    [100.0, 100.0]
    """
    ta, ua, ya = (np.asarray(v, dtype=np.float64) for v in (t, u, y))
    x = simulate_fopdt_at(ta, ua, K, tau, max(theta, 0.0))
    start = np.exp(-(ta - ta[0]) / tau)
    basis = np.column_stack([np.ones_like(ta), start])
    sd = max(float(np.std(ya)), 1e-300)

    def fit(rows: slice, judged: slice) -> float:
        coef = np.linalg.lstsq(basis[rows], (ya - x)[rows], rcond=None)[0]
        err = ya[judged] - x[judged] - basis[judged] @ coef
        return 100.0 * (1.0 - float(np.sqrt(np.mean(err**2))) / sd)

    cut = (2 * ta.size) // 3
    return fit(slice(None), slice(None)), fit(slice(0, cut), slice(cut, None))


def judge(
    K: float | None,
    tau: float | None,
    theta: float | None,
    warnings: Sequence[str],
    t: npt.ArrayLike,
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    *,
    honours_time: bool = False,
    peer: dict[str, Any] | None = None,
    converged: bool | None = None,
    reason: str | None = None,
    at_rest: dict[str, Any] | None = None,
) -> Verdict:
    """The verdict on one model of one record (see the module's docstring for the checks).

    Parameters
    ----------
    K, tau, theta : float or None
        The model (``theta`` None: no dead time).
    warnings : sequence of str
        The method's warnings.
    t, u, y : array_like
        The record at its time stamps.
    honours_time : bool, optional
        The method simulates at the time stamps (jitter and gaps are notes).
    peer : dict, optional
        An independent estimate: ``method``, ``K``, ``tau``, ``theta``.
    converged : bool, optional
        For a recursive or windowed estimate: whether it converged.
    reason : str, optional
        Why the method gave no model (when ``K`` or ``tau`` is None).
    at_rest : dict, optional
        For a record whose input is on from its first row: the estimate
        (``K``, ``tau``, ``u0``) that assumes the kit at rest, input off,
        before it. A model that differs from it by more than :data:`AGREE_REL`
        depends on what happened before the record, which the record does not
        show: its start is uncertain.

    Returns
    -------
    Verdict
    """
    notes = [w for w in warnings if _is_note(w, honours_time)]
    reasons = [w for w in warnings if not _is_note(w, honours_time)]
    if K is None or tau is None or not (math.isfinite(K) and math.isfinite(tau)) or tau <= 0:
        said = reason or "the method gave no first-order model"
        reasons.insert(0, note("no_model", reason=said))
        return Verdict(False, tuple(reasons), tuple(notes))
    th = 0.0 if theta is None or not math.isfinite(theta) else float(theta)
    with np.errstate(all="ignore"):
        fit_record, fit_holdout = free_run_fit(t, u, y, K, tau, th)
    fits_ok = math.isfinite(fit_record) and math.isfinite(fit_holdout)
    if not fits_ok or fit_record < MIN_FIT:
        reasons.append(note("poor_free_run_fit", fit=fit_record, minimum=MIN_FIT))
    elif fit_holdout < MIN_FIT:
        reasons.append(note("poor_prediction", fit=fit_holdout, minimum=MIN_FIT))
    agreement: dict[str, Any] = {}
    if peer is not None:
        agreement = dict(peer)
        pK, ptau, pth = peer.get("K"), peer.get("tau"), peer.get("theta")
        if pK is None or ptau is None:
            reasons.append(note("peer_gave_no_model", method=peer.get("method")))
        else:
            off = [
                f"{name} {mine:.4g} vs {theirs:.4g}"
                for name, mine, theirs in (("K", K, pK), ("tau", tau, ptau))
                if abs(mine / theirs - 1.0) > AGREE_REL
            ]
            if off:
                reasons.append(
                    note(
                        "disagrees_with_peer",
                        method=peer.get("method"),
                        off=", ".join(off),
                        apart=100 * AGREE_REL,
                    )
                )
            if abs(th - float(pth or 0.0)) > AGREE_THETA:
                reasons.append(
                    note(
                        "dead_time_uncertain",
                        here=th,
                        peer=float(pth or 0.0),
                        method=peer.get("method"),
                        apart=AGREE_THETA,
                    )
                )
    if at_rest is not None and at_rest.get("K") is not None:
        rK, rtau = float(at_rest["K"]), float(at_rest["tau"])
        if abs(K / rK - 1.0) > AGREE_REL or abs(tau / rtau - 1.0) > AGREE_REL:
            reasons.append(
                note("start_uncertain", u0=float(at_rest.get("u0", 0.0)), K=rK, tau=rtau)
            )
    if converged is False:
        reasons.append(note("not_converged"))
    return Verdict(
        not reasons,
        tuple(reasons),
        tuple(notes),
        round(fit_record, 3) if math.isfinite(fit_record) else None,
        round(fit_holdout, 3) if math.isfinite(fit_holdout) else None,
        agreement,
    )


def _is_note(warning: str, honours_time: bool) -> bool:
    if warning.startswith(NOTE_PREFIXES):
        return True
    return honours_time and warning.startswith(TIMING_PREFIXES)
