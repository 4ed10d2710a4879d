"""Adaptive PID: an online identifier's model retunes the gains, within bounds.

The paper motivates the recursive method by adaptive control: "the controller
parameters can be automatically adjusted in real time by the estimated
mathematical model". :class:`AdaptiveTuner` does that: every sample goes to an
online identifier (WLSM from :func:`thermolab.ident.make_identifier`, or any
object with ``update(u, y) -> estimate | None``); every ``every`` samples the
latest estimate, if it is valid, is tuned by a rule of
:mod:`thermolab.control.tuning`, and the new gains are limited in how fast
(``max_change``: relative change per retune) and how far (:class:`GainBounds`)
they may move from the gains in force.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from thermolab.control.pid import GAIN_LIMITS, PIDGains
from thermolab.control.tuning import FOPDT, RULES, tune
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

    Default: the published :data:`~thermolab.control.pid.GAIN_LIMITS`.
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

    Examples
    --------
    >>> class Known:  # an identifier that always knows the plant
    ...     def update(self, u, y):
    ...         return FOPDT(1.0, 10.0, 2.0)
    >>> tuner = AdaptiveTuner(Known(), "simc", every=1, tau_c=2.0, max_change=0.5)
    >>> start = PIDGains(1.0, 10.0)
    >>> g = tuner.update(0.0, 0.0, start)
    >>> g.Kp, g.Ti  # SIMC says 2.5 and 10; the rate limit stops Kp at 1.5
    (1.5, 10.0)
    """

    def __init__(
        self,
        identifier: Any,
        rule: str = "simc",
        *,
        every: int = 50,
        form: str | None = None,
        tau_c: float | None = None,
        theta: float = 0.0,
        max_change: float = 0.2,
        bounds: GainBounds | None = None,
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
        self.last_reason = ""
        self._latest: Any = None

    def update(self, u: float, y: float, current: PIDGains) -> PIDGains | None:
        """Feed one sample; every ``every`` samples return new gains (else ``None``).

        ``None`` also when the latest estimate is missing or not valid, or
        cannot be tuned (``last_reason`` says why).
        """
        estimate = self.identifier.update(u, y)
        if estimate is not None:
            self._latest = estimate
        self.samples += 1
        if self.samples % self.every:
            return None
        gains = self._retune(current)
        if gains is None:
            self.skipped += 1
        else:
            self.retunes += 1
        return gains

    def _retune(self, current: PIDGains) -> PIDGains | None:
        est = self._latest
        if est is None or not bool(getattr(est, "valid", True)):
            self.last_reason = "no valid estimate yet"
            return None
        try:
            theta = getattr(est, "theta", None)
            model = FOPDT(
                float(est.K), float(est.tau), self.theta if theta is None else float(theta)
            )
            target = tune(model, self.rule, form=self.form, tau_c=self.tau_c).gains
        except (InvalidParameterError, AttributeError, TypeError, ValueError) as exc:
            self.last_reason = f"estimate not tunable: {exc}"
            return None
        if math.copysign(1.0, target.Kp) != math.copysign(1.0, current.Kp):
            self.last_reason = "the estimate's gain has the wrong sign"
            return None
        c = self.max_change
        b = self.bounds
        sign = math.copysign(1.0, current.Kp)
        kp = _clip(abs(target.Kp), abs(current.Kp) / (1 + c), abs(current.Kp) * (1 + c))
        ti = _clip(target.Ti, current.Ti / (1 + c), current.Ti * (1 + c))
        td_step = c * max(current.Td, current.Ti / 4)
        td = _clip(target.Td, current.Td - td_step, current.Td + td_step)
        self.last_reason = ""
        return PIDGains(sign * _clip(kp, *b.kp), _clip(ti, *b.ti), _clip(td, *b.td))

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
            "retunes": self.retunes,
            "skipped": self.skipped,
        }
