"""Adaptive PID: an online identifier's model retunes the gains, within bounds.

The paper motivates the recursive method by adaptive control: "the controller
parameters can be automatically adjusted in real time by the estimated
mathematical model". :class:`AdaptiveTuner` does that: every sample goes to an
online identifier (WLSM from :func:`thermolab.ident.make_identifier`, or any
object with ``update(u, y) -> estimate | None``); every ``every`` samples the
latest estimate, if it is trusted, is tuned by a rule of
:mod:`thermolab.control.tuning`, and the new gains are limited in how fast
(``max_change``: relative change per retune) and how far (:class:`GainBounds`)
they may move from the gains in force.

Trusted means, for the estimate at a retune: valid (a first-order meaning);
passing the caller's ``trust`` check (the runner gives it
:func:`thermolab.ident.diagnostics.plausibility_warnings` and the estimate's
own warnings: this package may not import :mod:`thermolab.ident`); *settled*
— every estimate since the last retune valid and within ``settle_tol`` of it;
and *excited* — the input moved by at least ``excitation`` of its range over
that interval. In closed loop at a steady set point the input hardly moves,
and a recursive estimator with forgetting then loses the time constant while
keeping the gain (the kit's twin drifts to tau of 4-8 s for a 140 s plant):
retuning from it drove the integral time to a few seconds. Each hold says why
(``last_reason``), so a page can show it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from thermolab.control.parameters import PARAMETERS
from thermolab.control.pid import GAIN_LIMITS, PIDGains
from thermolab.control.tuning import FOPDT, RULES, tune
from thermolab.control.words import LoopWord, word_of
from thermolab.errors import InvalidParameterError

__all__ = ["AdaptiveTuner", "GainBounds"]


def _range(name: str, pair: tuple[float, float]) -> tuple[float, float]:
    low, high = (float(x) for x in pair)
    lim_low, lim_high = GAIN_LIMITS[name]
    if not (lim_low <= low <= high <= lim_high):
        raise InvalidParameterError(
            f"bounds of {name} must satisfy {lim_low:g} <= low <= high <= {lim_high:g}, "
            f"got ({low:g}, {high:g})"
        )
    return (low, high)


@dataclass(frozen=True, slots=True)
class GainBounds:
    """How far adaptive gains may go (absolute, inclusive).

    Parameters
    ----------
    kp : (float, float)
        Range of ``|Kp|`` (the sign stays the plant's).
    ti, td : (float, float)
        Ranges of ``Ti`` and ``Td`` in seconds.

    Notes
    -----
    The defaults are the published :data:`~thermolab.control.pid.GAIN_LIMITS`.
    """

    kp: tuple[float, float] = field(default=GAIN_LIMITS["kp"])
    ti: tuple[float, float] = field(default=GAIN_LIMITS["ti"])
    td: tuple[float, float] = field(default=GAIN_LIMITS["td"])

    def __post_init__(self) -> None:
        for name in ("kp", "ti", "td"):
            object.__setattr__(self, name, _range(name, getattr(self, name)))

    def to_dict(self) -> dict[str, list[float]]:
        """Return ``{"kp": [low, high], "ti": [...], "td": [...]}``."""
        return {"kp": list(self.kp), "ti": list(self.ti), "td": list(self.td)}


def _clip(x: float, low: float, high: float) -> float:
    return min(max(x, low), high)


class AdaptiveTuner:
    """Retune a PID from an online identifier's estimates.

    Parameters
    ----------
    identifier : object
        ``update(u, y) -> estimate | None``; an estimate has ``K``, ``tau``,
        ``valid`` and optionally ``theta``.
    rule : str, optional
        Tuning rule (default ``"simc"``; see :data:`~thermolab.control.tuning.RULES`).
    every : int, optional
        Retune every this many samples (default 50).
    form, tau_c : optional
        Passed to :func:`~thermolab.control.tuning.tune`.
    theta : float, optional
        Dead time (s) used when the estimates carry none (default 0).
    max_change : float, optional
        Largest relative change of ``Kp`` and ``Ti`` per retune (default 0.2:
        20 %); ``Td`` may move by ``max_change · max(Td, Ti/4)``.
    bounds : GainBounds, optional
        Absolute ranges of the gains.
    settle_tol : float, optional
        Retune only if every estimate since the last retune was valid and its
        ``K`` and ``tau`` within this fraction of the latest (default 0.1).
    excitation : float, optional
        Retune only if the input's peak-to-peak since the last retune is at
        least this fraction of the input range (default 0.05; 0 turns the check
        off; the range is set by :meth:`set_input_range`, else never checked).
    trust : callable, optional
        ``trust(estimate) -> reason or None``: an extra check of the estimate
        (plausibility, the identifier's warnings); a reason holds the gains.

    Examples
    --------
    >>> class Known:  # an identifier that always knows the plant
    ...     def update(self, u, y):
    ...         return FOPDT(1.0, 10.0, 2.0)
    >>> tuner = AdaptiveTuner(Known(), "simc", every=1, tau_c=2.0, max_change=0.5, excitation=0)
    >>> start = PIDGains(1.0, 10.0)
    >>> g = tuner.update(0.0, 0.0, start)
    >>> g.Kp, g.Ti  # SIMC says 2.5 and 10; the rate limit stops Kp at 1.5
    (1.5, 10.0)
    """

    def __init__(
        self,
        identifier: Any,
        rule: str = PARAMETERS["rule"].default,
        *,
        every: int = PARAMETERS["every"].default,
        form: str | None = None,
        tau_c: float | None = None,
        theta: float = 0.0,
        max_change: float = PARAMETERS["max_change"].default,
        bounds: GainBounds | None = None,
        settle_tol: float = PARAMETERS["settle_tol"].default,
        excitation: float = PARAMETERS["excitation"].default,
        trust: Callable[[Any], str | None] | None = None,
    ) -> None:
        if not callable(getattr(identifier, "update", None)):
            raise InvalidParameterError(
                f"the identifier needs an update(u, y) method, got {type(identifier).__name__}"
            )
        if rule not in RULES:
            raise InvalidParameterError(
                f"unknown tuning rule {rule!r}; choose one of {', '.join(RULES)}"
            )
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise InvalidParameterError(f"every must be an integer >= 1, got {every!r}")
        if not (math.isfinite(max_change) and 0 < max_change <= 10):
            raise InvalidParameterError(f"max_change must be in (0, 10], got {max_change!r}")
        if not (math.isfinite(theta) and theta >= 0):
            raise InvalidParameterError(f"theta must be a number of seconds >= 0, got {theta!r}")
        PARAMETERS["settle_tol"].check(settle_tol)
        PARAMETERS["excitation"].check(excitation)
        if trust is not None and not callable(trust):
            raise InvalidParameterError("trust must be callable: trust(estimate) -> reason | None")
        self.identifier = identifier
        self.rule = rule
        self.every = every
        self.form = form
        self.tau_c = tau_c
        self.theta = float(theta)
        self.max_change = float(max_change)
        self.bounds = bounds if bounds is not None else GainBounds()
        self.samples = 0
        self.retunes = 0
        self.skipped = 0
        self.settle_tol = float(settle_tol)
        self.excitation = float(excitation)
        self._trust = trust
        self.input_span = math.nan
        self.last_reason = ""
        #: ``last_reason`` by its code and values (thermolab.control.words), for a page.
        self.last_word: LoopWord | None = None
        self._latest: Any = None
        self._reset_interval()

    def set_input_range(self, low: float, high: float) -> None:
        """The input range the ``excitation`` check measures against (the rig's)."""
        self.input_span = float(high) - float(low)

    def _reset_interval(self) -> None:
        self._unsettled = False
        self._k_range = [math.inf, -math.inf]
        self._tau_range = [math.inf, -math.inf]
        # The next interval starts from the input in force: a step right after a retune
        # counts as movement.
        last = getattr(self, "_last_u", math.nan)
        self._u_range = [last, last] if math.isfinite(last) else [math.inf, -math.inf]

    def _note(self, u: float, estimate: Any) -> None:
        ur = self._u_range
        ur[0], ur[1] = min(ur[0], u), max(ur[1], u)
        self._last_u = u
        if estimate is None:
            return
        if not bool(getattr(estimate, "valid", True)):
            self._unsettled = True
            return
        try:
            K, tau = float(estimate.K), float(estimate.tau)
        except (AttributeError, TypeError, ValueError):
            self._unsettled = True
            return
        kr, tr = self._k_range, self._tau_range
        kr[0], kr[1] = min(kr[0], K), max(kr[1], K)
        tr[0], tr[1] = min(tr[0], tau), max(tr[1], tau)

    def update(self, u: float, y: float, current: PIDGains) -> PIDGains | None:
        """Feed one sample; every ``every`` samples return new gains (else ``None``).

        ``None`` also when the latest estimate is missing or not valid, or
        cannot be tuned (``last_reason`` says why).
        """
        estimate = self.identifier.update(u, y)
        if estimate is not None:
            self._latest = estimate
        self._note(float(u), estimate)
        self.samples += 1
        if self.samples % self.every:
            return None
        try:
            gains = self._retune(current)
        finally:
            self._reset_interval()
        if gains is None:
            self.skipped += 1
        else:
            self.retunes += 1
        return gains

    def _hold(self, word: LoopWord | None) -> None:
        self.last_word = word
        self.last_reason = "" if word is None else word.text

    def _retune(self, current: PIDGains) -> PIDGains | None:
        est = self._latest
        if est is None or not bool(getattr(est, "valid", True)):
            self._hold(LoopWord.of("hold.no_estimate"))
            return None
        held = self._untrusted(est)
        if held is not None:
            self._hold(held)
            return None
        try:
            theta = getattr(est, "theta", None)
            model = FOPDT(
                float(est.K), float(est.tau), self.theta if theta is None else float(theta)
            )
            target = tune(model, self.rule, form=self.form, tau_c=self.tau_c).gains
        except (InvalidParameterError, AttributeError, TypeError, ValueError) as exc:
            # A declared sentence says why in the reader's language; else the error's English.
            self._hold(word_of(exc) or LoopWord.of("hold.not_tunable", reason=str(exc)))
            return None
        if math.copysign(1.0, target.Kp) != math.copysign(1.0, current.Kp):
            self._hold(LoopWord.of("hold.wrong_sign"))
            return None
        c = self.max_change
        b = self.bounds
        sign = math.copysign(1.0, current.Kp)
        kp = _clip(abs(target.Kp), abs(current.Kp) / (1 + c), abs(current.Kp) * (1 + c))
        ti = _clip(target.Ti, current.Ti / (1 + c), current.Ti * (1 + c))
        td_step = c * max(current.Td, current.Ti / 4)
        td = _clip(target.Td, current.Td - td_step, current.Td + td_step)
        self._hold(None)
        return PIDGains(sign * _clip(kp, *b.kp), _clip(ti, *b.ti), _clip(td, *b.td))

    def _untrusted(self, est: Any) -> LoopWord | None:
        """Why the latest estimate must not retune the PID, or ``None``."""
        if self._trust is not None:
            reason = self._trust(est)
            if reason:
                return LoopWord.of("hold.not_trusted", warning=str(reason))
        K, tau = float(est.K), float(est.tau)
        tol = self.settle_tol
        if self._unsettled:
            return LoopWord.of("hold.unsettled_invalid", every=self.every)
        for name, value, (low, high) in (("K", K, self._k_range), ("tau", tau, self._tau_range)):
            if low <= high and (high - value > tol * abs(value) or value - low > tol * abs(value)):
                return LoopWord.of(
                    "hold.unsettled_moved", name=name, low=low, high=high, every=self.every,
                    tolerance=100 * tol, value=value,
                )  # fmt: skip
        span = self.input_span
        moved = self._u_range[1] - self._u_range[0]
        if self.excitation > 0 and math.isfinite(span) and moved < self.excitation * span:
            return LoopWord.of(
                "hold.little_excitation", moved=moved, every=self.every,
                share=100 * self.excitation,
            )  # fmt: skip
        return None

    def to_dict(self) -> dict[str, Any]:
        """Return the configuration and counters (JSON-ready)."""
        return {
            "rule": self.rule,
            "every": self.every,
            "form": self.form,
            "tau_c": self.tau_c,
            "theta": self.theta,
            "max_change": self.max_change,
            "bounds": self.bounds.to_dict(),
            "settle_tol": self.settle_tol,
            "excitation": self.excitation,
            "retunes": self.retunes,
            "skipped": self.skipped,
            "last_reason": self.last_reason,
            "last_word": None if self.last_word is None else self.last_word.to_dict(),
        }
