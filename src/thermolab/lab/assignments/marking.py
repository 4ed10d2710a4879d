"""Automatic assessment of a hand-in: a student's Ks, Ts and θ against the truth, a pure function.

:func:`assess` judges each quantity the student gave twice, where it can:

* against the rig's **reference model** (a twin's true parameters,
  :func:`thermolab.lab.assignments.reference.reference_model`), when the rig
  has one: did the experiment and its analysis find the plant?
* against the **run's own identification** (the record identified again with
  the assignment's methods, :mod:`thermolab.lab.assignments.identify`): did
  the student compute what their own data say? The answer passes if it is
  within tolerance of at least one *trusted* method's estimate.

The mark (scheme ``checks``): one point per check passed, scaled to
:data:`MARK_MAX` (10) — ``MARK_MAX × passed / checks``, rounded to one
decimal. When none of the identifications of the run is trusted (the
library's warnings: undetermined operating point, residuals not white, an
estimate that did not converge...), the checks against the data cannot be
judged: the assessment has **no mark** (``mark`` is ``None``, state
``review``) and the feedback says why, so nothing final-looking is shown; the
teacher decides. Nothing here reads a database or a clock.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from thermolab.errors import InvalidParameterError

__all__ = [
    "MARK_MAX",
    "QUANTITIES",
    "Answers",
    "Assessment",
    "Check",
    "Identified",
    "Reference",
    "Tolerances",
    "assess",
    "within",
]

#: The highest mark.
MARK_MAX = 10.0
#: The quantities a student answers, in the order they are shown.
QUANTITIES: tuple[str, ...] = ("K", "tau", "theta")

Quantity = Literal["K", "tau", "theta"]
Basis = Literal["reference", "run"]
Verdict = Literal["pass", "fail", "not_judged"]
State = Literal["marked", "review"]


@dataclass(frozen=True, slots=True)
class Tolerances:
    """How far an answer may be from its target.

    Attributes
    ----------
    K, tau : float
        Relative tolerances on the gain Ks and the time constant Ts (0.1: ±10 %).
    theta : float or None
        Absolute tolerance on the dead time θ, seconds; ``None``: θ is not asked.
    """

    K: float = 0.1
    tau: float = 0.1
    theta: float | None = None

    def __post_init__(self) -> None:
        for name in ("K", "tau"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and 0 < value <= 1):
                raise InvalidParameterError(
                    f"the relative tolerance on {name} must be above 0 and at most 1, got {value!r}"
                )
        if self.theta is not None and not (math.isfinite(self.theta) and 0 < self.theta <= 3600):
            raise InvalidParameterError(
                f"the tolerance on theta must be above 0 and at most 3600 s, got {self.theta!r}"
            )

    def quantities(self) -> tuple[Quantity, ...]:
        """The quantities this assignment asks for (θ only with a tolerance)."""
        return ("K", "tau") if self.theta is None else ("K", "tau", "theta")

    def describe(self, quantity: Quantity) -> str:
        """The tolerance as a student reads it (``"±10 %"``, ``"±5 s"``)."""
        if quantity == "theta":
            return f"±{self.theta:g} s"
        return f"±{100 * getattr(self, quantity):g} %"

    def to_dict(self) -> dict[str, float | None]:
        """``{"K", "tau", "theta"}``."""
        return {"K": self.K, "tau": self.tau, "theta": self.theta}


@dataclass(frozen=True, slots=True)
class Answers:
    """What the student computed: Ks, Ts (s), θ (s, optional) and a short conclusion."""

    K: float
    tau: float
    theta: float | None = None
    conclusion: str = ""

    def get(self, quantity: Quantity) -> float | None:
        """The answer for ``quantity`` (``None`` if not given)."""
        value: float | None = getattr(self, quantity)
        return value

    def to_dict(self) -> dict[str, Any]:
        """``{"K", "tau", "theta", "conclusion"}``."""
        return {"K": self.K, "tau": self.tau, "theta": self.theta, "conclusion": self.conclusion}


@dataclass(frozen=True, slots=True)
class Reference:
    """A rig's true first-order model plus dead time (a twin's parameters)."""

    K: float
    tau: float
    theta: float
    source: str = ""

    def get(self, quantity: Quantity) -> float:
        """The reference value of ``quantity``."""
        value: float = getattr(self, quantity)
        return value

    def to_dict(self) -> dict[str, Any]:
        """``{"K", "tau", "theta", "source"}``."""
        return {"K": self.K, "tau": self.tau, "theta": self.theta, "source": self.source}


@dataclass(frozen=True, slots=True)
class Identified:
    """One method's identification of the handed-in run, as the library judged it.

    Attributes
    ----------
    method : str
        A registry name (``"lsm"``, ``"oe"``...).
    K, tau, theta : float or None
        Its estimates (``None`` where it has none).
    fit : float or None
        The simulation's NRMSE fit %, where the method computes one.
    trusted : bool
        The library's verdict (:func:`thermolab.ident.assess.assess`).
    warnings : tuple of str
        Why it is not trusted, then the notes, in the library's words.
    """

    method: str
    K: float | None
    tau: float | None
    theta: float | None
    fit: float | None
    trusted: bool
    warnings: tuple[str, ...] = ()

    def get(self, quantity: Quantity) -> float | None:
        """The estimate of ``quantity``, or ``None``."""
        value: float | None = getattr(self, quantity)
        return value if value is not None and math.isfinite(value) else None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "method": self.method,
            "K": self.get("K"),
            "tau": self.get("tau"),
            "theta": self.get("theta"),
            "fit": self.fit if self.fit is not None and math.isfinite(self.fit) else None,
            "trusted": self.trusted,
            "warnings": list(self.warnings),
        }


@dataclass(frozen=True, slots=True)
class Check:
    """One answer compared with one target: what, against what, and why it passed or not."""

    quantity: Quantity
    basis: Basis
    answer: float | None
    target: float | None
    tolerance: str
    verdict: Verdict
    why: str
    method: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "quantity": self.quantity,
            "basis": self.basis,
            "answer": self.answer,
            "target": self.target,
            "tolerance": self.tolerance,
            "verdict": self.verdict,
            "why": self.why,
            "method": self.method,
        }


@dataclass(frozen=True, slots=True)
class Assessment:
    """The result of :func:`assess`: the checks, the mark (or why there is none)."""

    checks: tuple[Check, ...]
    mark: float | None
    max: float
    state: State
    notes: tuple[str, ...] = ()
    identified: tuple[Identified, ...] = field(default=())
    reference: Reference | None = None
    tolerances: Tolerances | None = None

    @property
    def passed(self) -> int:
        """Checks passed."""
        return sum(c.verdict == "pass" for c in self.checks)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (stored with the hand-in, shown to the student)."""
        return {
            "scheme": "checks",
            "mark": self.mark,
            "max": self.max,
            "state": self.state,
            "passed": self.passed,
            "checks": [c.to_dict() for c in self.checks],
            "notes": list(self.notes),
            "identified": [i.to_dict() for i in self.identified],
            "reference": None if self.reference is None else self.reference.to_dict(),
            "tolerances": None if self.tolerances is None else self.tolerances.to_dict(),
        }


def within(answer: float, target: float, quantity: Quantity, tolerances: Tolerances) -> bool:
    """Whether ``answer`` is within the tolerance of ``target`` (inclusive).

    Relative for Ks and Ts (``|answer − target| ≤ tol·|target|``), absolute for θ.

    Examples
    --------
    >>> within(0.15, 0.14, "K", Tolerances(K=0.1))
    True
    >>> within(0.16, 0.14, "K", Tolerances(K=0.1))
    False
    >>> within(20.0, 16.0, "theta", Tolerances(theta=5.0))
    True
    """
    if not (math.isfinite(answer) and math.isfinite(target)):
        return False
    if quantity == "theta":
        assert tolerances.theta is not None
        allowed = tolerances.theta
    else:
        allowed = getattr(tolerances, quantity) * abs(target)
    # A rounding margin: an answer typed from the shown figure is not failed by the last bit.
    return abs(answer - target) <= allowed * (1 + 1e-9) + 1e-12


def assess(
    answers: Answers,
    tolerances: Tolerances,
    reference: Reference | None,
    identified: Sequence[Identified],
) -> Assessment:
    """Mark a student's answers against the reference model and the run's identification.

    Parameters
    ----------
    answers : Answers
    tolerances : Tolerances
    reference : Reference or None
        The rig's true model; ``None`` for a rig without one (real hardware).
    identified : sequence of Identified
        The run identified again with each of the assignment's methods.

    Returns
    -------
    Assessment
        ``mark`` is ``None`` (state ``"review"``) when no identification of the
        run is trusted, or there is nothing to check against.

    Examples
    --------
    >>> ref = Reference(0.14, 250.0, 0.0)
    >>> run = Identified("lsm", 0.141, 248.0, 0.0, 95.0, True)
    >>> a = assess(Answers(0.14, 250.0), Tolerances(), ref, [run])
    >>> a.mark, a.state, a.passed
    (10.0, 'marked', 4)
    >>> assess(Answers(0.2, 250.0), Tolerances(), ref, [run]).mark
    5.0
    """
    checks: list[Check] = []
    notes: list[str] = []
    trusted = [i for i in identified if i.trusted]
    for item in identified:
        if not item.trusted:
            why = "; ".join(item.warnings) or "its model is not valid"
            notes.append(f"the {item.method} identification of your run is not trustworthy: {why}")
    for quantity in tolerances.quantities():
        answer = answers.get(quantity)
        told = tolerances.describe(quantity)
        if reference is not None:
            checks.append(
                _check(quantity, "reference", answer, reference.get(quantity), tolerances)
            )
        checks.append(_run_check(quantity, answer, identified, trusted, tolerances, told))
    judged = [c for c in checks if c.verdict != "not_judged"]
    review = not trusted or not judged
    if not identified:
        notes.append("the run could not be identified with the assignment's methods")
    if review:
        notes.append("no mark is given: your teacher will review this hand-in")
        return Assessment(
            tuple(checks), None, MARK_MAX, "review", tuple(notes), tuple(identified), reference,
            tolerances,
        )  # fmt: skip
    passed = sum(c.verdict == "pass" for c in judged)
    mark = round(MARK_MAX * passed / len(judged), 1)
    return Assessment(
        tuple(checks), mark, MARK_MAX, "marked", tuple(notes), tuple(identified), reference,
        tolerances,
    )  # fmt: skip


def _check(
    quantity: Quantity,
    basis: Basis,
    answer: float | None,
    target: float | None,
    tolerances: Tolerances,
    method: str | None = None,
) -> Check:
    told = tolerances.describe(quantity)
    where = "the rig's reference model" if basis == "reference" else f"your run's {method} estimate"
    if answer is None or not math.isfinite(answer):
        return Check(quantity, basis, None, target, told, "fail", "no answer was given", method)
    if target is None or not math.isfinite(target):
        why = f"{where} has no value for it"
        return Check(quantity, basis, answer, None, told, "not_judged", why, method)
    if within(answer, target, quantity, tolerances):
        why = f"within {told} of {where} ({target:.6g})"
        return Check(quantity, basis, answer, target, told, "pass", why, method)
    off = _how_far(answer, target, quantity)
    why = f"{off} from {where} ({target:.6g}), more than {told}"
    return Check(quantity, basis, answer, target, told, "fail", why, method)


def _run_check(
    quantity: Quantity,
    answer: float | None,
    identified: Sequence[Identified],
    trusted: Sequence[Identified],
    tolerances: Tolerances,
    told: str,
) -> Check:
    if not trusted:
        why = (
            "not judged: no identification of your run is trustworthy"
            if identified
            else "not judged: your run could not be identified"
        )
        return Check(quantity, "run", answer, None, told, "not_judged", why)
    candidates = [
        _check(quantity, "run", answer, i.get(quantity), tolerances, i.method) for i in trusted
    ]
    for verdict in ("pass", "fail", "not_judged"):
        for candidate in candidates:
            if candidate.verdict == verdict:
                return candidate
    return candidates[0]  # pragma: no cover - every verdict is one of the three


def _how_far(answer: float, target: float, quantity: Quantity) -> str:
    if quantity == "theta" or target == 0:
        return f"{abs(answer - target):.3g} s off" if quantity == "theta" else "off"
    return f"{100 * abs(answer - target) / abs(target):.3g} % off"
