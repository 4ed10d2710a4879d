"""PID tuning rules for a first-order-plus-dead-time (FOPDT) model.

A model is ``G(s) = K e^{-θs} / (τs + 1)``. Every rule below gives a
:class:`Tuning` in the parallel form of :class:`~thermolab.control.pid.PID`
(``Kp``, ``Ti``, ``Td``). The rules and their sources:

* ``imc`` — IMC / lambda tuning (Rivera, Morari & Skogestad 1986, Table 1;
  Seborg et al., *Process Dynamics and Control*, Table 12.1), closed-loop time
  constant ``λ``:

  - PI:  ``Kp = τ / (K(λ + θ))``, ``Ti = τ``;
  - PID (first-order Padé of the delay):
    ``Kp = (τ + θ/2) / (K(λ + θ/2))``, ``Ti = τ + θ/2``, ``Td = τθ / (2τ + θ)``.

* ``simc`` — Skogestad's SIMC (J. Process Control 13, 2003, eq. 19-20),
  closed-loop time constant ``τc``:

  - PI: ``Kp = τ / (K(τc + θ))``, ``Ti = min(τ, 4(τc + θ))``.
    SIMC gives a PID only for second-order models, so for an FOPDT it is PI only.

* ``zn`` — Ziegler–Nichols open loop (reaction curve; Ziegler & Nichols 1942):

  - PI:  ``Kp = 0.9τ / (Kθ)``, ``Ti = θ / 0.3``;
  - PID: ``Kp = 1.2τ / (Kθ)``, ``Ti = 2θ``, ``Td = θ / 2``.

* ``cc`` — Cohen–Coon (1953; Seborg et al. Table 12.3), with ``r = θ/τ``:

  - PI:  ``Kp = (τ/(Kθ))(0.9 + r/12)``, ``Ti = θ(30 + 3r) / (9 + 20r)``;
  - PID: ``Kp = (τ/(Kθ))(4/3 + r/4)``, ``Ti = θ(32 + 6r) / (13 + 8r)``,
    ``Td = 4θ / (11 + 2r)``.

The closed-loop speed (``tau_c``, λ for IMC) applies to ``imc`` and ``simc``;
its default is ``θ`` (Skogestad's "tight control" choice), or ``τ/10`` for a
model without dead time. ``zn`` and ``cc`` need ``θ > 0``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from thermolab.control.pid import PIDGains
from thermolab.control.words import LoopWord
from thermolab.errors import InvalidParameterError, ModelValueError, RuleNotApplicableError

__all__ = [
    "FOPDT",
    "RULES",
    "RULE_FORMS",
    "SPEED_RULES",
    "STEP_FRACTION",
    "Tuning",
    "as_fopdt",
    "step_setpoint",
    "tune",
]

Rule = Literal["imc", "simc", "zn", "cc"]
Form = Literal["pi", "pid"]

#: The rules, with a one-line description each (for menus and ``--help``).
RULES: dict[str, str] = {
    "imc": "IMC / lambda tuning (Rivera, Morari & Skogestad 1986)",
    "simc": "SIMC (Skogestad 2003)",
    "zn": "Ziegler-Nichols open loop (reaction curve, 1942)",
    "cc": "Cohen-Coon (1953)",
}
#: The forms each rule defines for an FOPDT model; the first is the default.
RULE_FORMS: dict[str, tuple[str, ...]] = {
    "imc": ("pid", "pi"),
    "simc": ("pi",),
    "zn": ("pid", "pi"),
    "cc": ("pid", "pi"),
}
#: The rules that take a closed-loop speed (``tau_c``, λ for IMC).
SPEED_RULES: tuple[str, ...] = ("imc", "simc")


#: A tuning step's input, as a fraction of the way from the rest input to the farther
#: end of the input's range (:func:`step_setpoint`).
STEP_FRACTION = 0.5


@dataclass(frozen=True, slots=True)
class FOPDT:
    """A first-order-plus-dead-time model ``K e^{-θs} / (τs + 1)``.

    Parameters
    ----------
    K : float
        Static gain (output unit per input unit), finite and non-zero.
    tau : float
        Time constant in seconds, > 0.
    theta : float, optional
        Dead time in seconds, >= 0 (default 0).

    Examples
    --------
    >>> FOPDT(0.6, 140.0, 15.9).to_dict()
    {'K': 0.6, 'tau': 140.0, 'theta': 15.9}
    """

    K: float
    tau: float
    theta: float = 0.0

    def __post_init__(self) -> None:
        for code, value, valid in (
            ("model_gain_invalid", self.K, math.isfinite(self.K) and self.K != 0),
            ("model_tau_invalid", self.tau, math.isfinite(self.tau) and self.tau > 0),
            ("model_theta_invalid", self.theta, math.isfinite(self.theta) and self.theta >= 0),
        ):
            if not valid:
                word = LoopWord.of(code, value=value)
                raise ModelValueError(word.text, word_code=code, word_params=word.params)

    def to_dict(self) -> dict[str, float]:
        """Return ``{"K", "tau", "theta"}`` (JSON-ready)."""
        return {"K": self.K, "tau": self.tau, "theta": self.theta}


def as_fopdt(model: Any) -> FOPDT:
    """Read an FOPDT model from a tuple ``(K, tau[, theta])`` or any object with ``K``/``tau``.

    ``theta`` is read when the object has it (``0`` otherwise); an identified
    estimate that is not valid is refused.

    Raises
    ------
    InvalidParameterError
        If the values are missing, not valid, or out of range.

    Examples
    --------
    >>> as_fopdt((2.0, 10.0, 1.0))
    FOPDT(K=2.0, tau=10.0, theta=1.0)
    """
    if isinstance(model, FOPDT):
        return model
    if isinstance(model, tuple | list):
        if len(model) not in (2, 3):
            raise InvalidParameterError(f"a model is (K, tau) or (K, tau, theta), got {model!r}")
        try:
            return FOPDT(*(float(x) for x in model))
        except (TypeError, ValueError) as exc:
            if isinstance(exc, InvalidParameterError):
                raise
            raise InvalidParameterError(
                f"a model's values must be numbers, got {model!r}"
            ) from None
    if getattr(model, "valid", True) is False:
        reason = getattr(model, "reason", None) or "no first-order meaning"
        raise InvalidParameterError(f"cannot tune from an invalid model ({reason})")
    try:
        K, tau = float(model.K), float(model.tau)
        theta = float(getattr(model, "theta", 0.0) or 0.0)
    except (AttributeError, TypeError, ValueError):
        raise InvalidParameterError(
            f"a model needs numeric K and tau (and optionally theta); got {type(model).__name__}"
        ) from None
    return FOPDT(K, tau, theta)


@dataclass(frozen=True, slots=True)
class Tuning:
    """What a tuning rule gave: the gains, the rule, the form and the speed.

    Attributes
    ----------
    gains : PIDGains
    rule : str
    form : str
        ``"pi"`` or ``"pid"``.
    tau_c : float or None
        The closed-loop time constant used (``imc``, ``simc``), else ``None``.
    model : FOPDT
    """

    gains: PIDGains
    rule: str
    form: str
    tau_c: float | None
    model: FOPDT

    @property
    def Kp(self) -> float:  # noqa: N802 - the textbook names
        """Proportional gain."""
        return self.gains.Kp

    @property
    def Ti(self) -> float:  # noqa: N802
        """Integral time (s)."""
        return self.gains.Ti

    @property
    def Td(self) -> float:  # noqa: N802
        """Derivative time (s)."""
        return self.gains.Td

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary."""
        return {
            "rule": self.rule,
            "form": self.form,
            "tau_c": self.tau_c,
            **self.gains.to_dict(),
            "model": self.model.to_dict(),
        }


def tune(
    model: Any,
    rule: str = "simc",
    *,
    form: str | None = None,
    tau_c: float | None = None,
) -> Tuning:
    """Tune a PI or PID from an FOPDT model by a named rule.

    Parameters
    ----------
    model : FOPDT, tuple or object with K, tau (and theta)
        The plant (see :func:`as_fopdt`).
    rule : {"imc", "simc", "zn", "cc"}
        The rule (see the module's docstring for the formulas).
    form : {"pi", "pid"}, optional
        Default: the rule's first form in :data:`RULE_FORMS`.
    tau_c : float, optional
        Closed-loop time constant in seconds (``imc``, ``simc``); default ``θ``
        (``τ/10`` when ``θ = 0``).

    Returns
    -------
    Tuning

    Raises
    ------
    InvalidParameterError
        For an unknown rule or form, a rule that needs dead time on a model
        without, a ``tau_c`` not > 0 or given to a rule without one, or gains
        outside :data:`~thermolab.control.pid.GAIN_LIMITS`.

    Examples
    --------
    >>> t = tune((1.0, 10.0, 2.0), "zn")
    >>> t.Kp, t.Ti, t.Td
    (6.0, 4.0, 1.0)
    >>> tune((0.6, 140.0, 15.9), "simc", tau_c=15.9).gains  # doctest: +ELLIPSIS
    PIDGains(Kp=7.337..., Ti=127.2, Td=0.0)
    """
    if rule not in RULES:
        raise InvalidParameterError(
            f"unknown tuning rule {rule!r}; choose one of {', '.join(RULES)}"
        )
    forms = RULE_FORMS[rule]
    chosen = forms[0] if form is None else form
    if chosen not in forms:
        raise InvalidParameterError(
            f"rule {rule!r} defines the form(s) {', '.join(forms)} for an FOPDT model, "
            f"not {chosen!r}"
        )
    m = as_fopdt(model)
    K, tau, theta = m.K, m.tau, m.theta
    speed: float | None = None
    if rule in SPEED_RULES:
        speed = (theta if theta > 0 else tau / 10.0) if tau_c is None else float(tau_c)
        if not (math.isfinite(speed) and speed > 0):
            raise InvalidParameterError(
                f"tau_c must be a positive number of seconds, got {tau_c!r}"
            )
    elif tau_c is not None:
        raise InvalidParameterError(f"rule {rule!r} has no closed-loop speed; drop tau_c")
    elif theta <= 0:
        word = LoopWord.of("needs_dead_time", rule=rule)
        raise RuleNotApplicableError(word.text, word_code=word.code, word_params=word.params)
    Td = 0.0
    if rule == "imc":
        assert speed is not None
        if chosen == "pi":
            Kp, Ti = tau / (K * (speed + theta)), tau
        else:
            Kp = (tau + theta / 2) / (K * (speed + theta / 2))
            Ti = tau + theta / 2
            Td = tau * theta / (2 * tau + theta)
    elif rule == "simc":
        assert speed is not None
        Kp, Ti = tau / (K * (speed + theta)), min(tau, 4 * (speed + theta))
    elif rule == "zn":
        if chosen == "pi":
            Kp, Ti = 0.9 * tau / (K * theta), theta / 0.3
        else:
            Kp, Ti, Td = 1.2 * tau / (K * theta), 2 * theta, theta / 2
    else:
        r = theta / tau
        if chosen == "pi":
            Kp = tau / (K * theta) * (0.9 + r / 12)
            Ti = theta * (30 + 3 * r) / (9 + 20 * r)
        else:
            Kp = tau / (K * theta) * (4 / 3 + r / 4)
            Ti = theta * (32 + 6 * r) / (13 + 8 * r)
            Td = 4 * theta / (11 + 2 * r)
    return Tuning(PIDGains(Kp, Ti, Td), rule, chosen, speed, m)


def step_setpoint(
    model: FOPDT,
    *,
    y0: float,
    u_rest: float,
    u_limits: tuple[float, float],
    output_limit: float | None = None,
    fraction: float = STEP_FRACTION,
) -> float:
    """A set point for a tuning step that a rig's own ranges make sensible.

    The output ``model`` settles at when the input steps from ``u_rest`` a
    ``fraction`` of the way to the farther end of ``u_limits`` (the paper's
    ±10 V box at rest at 0 V: to 5 V, 0.7 V up; a TCLab kit: to 50 %, about
    30 °C up), kept below ``output_limit`` (halfway from ``y0`` to it if the
    step would reach it), rounded to two significant digits of the step. The
    middle of the range is no default: on a range centred on the rest input
    it is no step at all.

    Raises
    ------
    InvalidParameterError
        If ``fraction`` is not in (0, 1] or the range holds no step from ``u_rest``.

    Examples
    --------
    >>> step_setpoint(FOPDT(0.14009, 250.0), y0=0.0, u_rest=0.0, u_limits=(-10.0, 10.0))
    0.7
    >>> step_setpoint(FOPDT(0.6, 140.0, 16.0), y0=21.3, u_rest=0.0, u_limits=(0.0, 100.0))
    51.0
    >>> step_setpoint(FOPDT(0.14, 250.0), y0=4.5, u_rest=0.0, u_limits=(-10.0, 10.0),
    ...               output_limit=5.0)
    4.75
    """
    if not 0.0 < fraction <= 1.0:
        raise InvalidParameterError(f"fraction must be in (0, 1], got {fraction!r}")
    low, high = u_limits
    far = high if high - u_rest >= u_rest - low else low
    if far == u_rest:
        raise InvalidParameterError(f"the input range {low:g} to {high:g} holds no step")
    target = y0 + model.K * fraction * (far - u_rest)
    if output_limit is not None and target >= output_limit > y0:
        target = y0 + 0.5 * (output_limit - y0)
    step = target - y0
    digits = 1 - math.floor(math.log10(abs(step)))
    return round(y0 + round(step, digits), max(digits, 0))
