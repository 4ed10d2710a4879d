"""The closed loop's parameters, each declared once: name, type, default, range, unit, help.

Every entry point reads this module instead of spelling a range out again:
:class:`~thermolab.control.pid.PIDGains` checks the gains against
:data:`~thermolab.control.pid.GAIN_LIMITS` (which this module publishes as
``kp``, ``ti``, ``td``), :class:`~thermolab.control.adaptive.AdaptiveTuner` its
settings, the lab's control requests their fields, and — through
:func:`control_json` — ``GET /api/control`` and the browser's "Closed loop"
panel, whose form is built from it. No NumPy here: a command line can list
the parameters at once.

How to add a parameter
    Declare one :class:`ControlParameter` in :data:`PARAMETERS` and read it
    where it acts (``PARAMETERS["name"].default``, ``.check(value)``); the API
    schema and the page follow.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Literal

from thermolab.control.pid import GAIN_LIMITS
from thermolab.control.tuning import RULE_FORMS, RULES, SPEED_RULES
from thermolab.errors import GainRangeError

__all__ = ["PARAMETERS", "ControlParameter", "control_json"]

ParameterType = Literal["number", "integer", "choice", "range"]


@dataclass(frozen=True, slots=True)
class ControlParameter:
    """One parameter of the closed loop.

    Parameters
    ----------
    name : str
        The keyword in the library and the JSON key.
    type : {"number", "integer", "choice", "range"}
        ``range`` is a pair ``[low, high]`` inside ``[minimum, maximum]``.
    default : object
        Used when the parameter is not given (``None``: derived, see ``help``).
    help : str
        One line for forms and option help.
    minimum, maximum : float or None
        Inclusive bounds (of a number, an integer or each end of a range).
    exclusive_minimum : bool
        ``minimum`` itself is not allowed.
    magnitude : bool
        The bounds apply to ``|value|`` (``Kp``: its sign is the plant's).
    choices : tuple of str
        The words of a ``choice``.
    unit : str
        Unit of the value (``"s"``; ``"input/output"`` for ``Kp``).
    """

    name: str
    type: ParameterType
    default: Any
    help: str
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    magnitude: bool = False
    choices: tuple[str, ...] = ()
    unit: str = ""

    def allowed(self) -> str:
        """What is allowed, in words (for error messages)."""
        if self.type == "choice":
            return "one of " + ", ".join(self.choices)
        low = "-inf" if self.minimum is None else f"{self.minimum:g}"
        high = "inf" if self.maximum is None else f"{self.maximum:g}"
        what = {"number": "a finite number", "integer": "an integer", "range": "[low, high]"}
        subject = f"|{self.name}|" if self.magnitude else self.name
        opening = "(" if self.exclusive_minimum else "["
        return f"{what[self.type]} with {subject} in {opening}{low}, {high}]"

    def _number(self, value: object) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise GainRangeError(f"{self.name} must be a number, got {value!r}")
        x = float(value)
        size = abs(x) if self.magnitude else x
        low_ok = (
            self.minimum is None
            or size > self.minimum
            or (not self.exclusive_minimum and size == self.minimum)
        )
        if not (math.isfinite(x) and low_ok and (self.maximum is None or size <= self.maximum)):
            raise GainRangeError(
                f"{self.name} = {value!r} is out of range; allowed: {self.allowed()}"
            )
        return x

    def check(self, value: object) -> Any:
        """Return ``value`` checked (``None`` passes: the default applies).

        Raises
        ------
        GainRangeError
            If it is not finite, not of the type, or outside the range.

        Examples
        --------
        >>> PARAMETERS["ti"].check(100)
        100.0
        >>> PARAMETERS["kp"].check(float("inf"))
        Traceback (most recent call last):
        ...
        thermolab.errors.GainRangeError: kp = inf is out of range; ...
        """
        if value is None:
            return None
        if self.type == "choice":
            if value not in self.choices:
                raise GainRangeError(f"{self.name} must be {self.allowed()}, got {value!r}")
            return value
        if self.type == "integer":
            if isinstance(value, bool) or not isinstance(value, int):
                raise GainRangeError(f"{self.name} must be an integer, got {value!r}")
            self._number(value)
            return value
        if self.type == "range":
            if not isinstance(value, list | tuple) or len(value) != 2:
                raise GainRangeError(f"{self.name} must be a pair [low, high], got {value!r}")
            low, high = (self._number(v) for v in value)
            if low > high:
                raise GainRangeError(f"{self.name} must have low <= high, got {list(value)!r}")
            return (low, high)
        return self._number(value)

    def to_json(self) -> dict[str, Any]:
        """The declaration as JSON (camelCase keys, like the method registry's)."""
        default = list(self.default) if isinstance(self.default, tuple) else self.default
        return {
            "name": self.name,
            "type": self.type,
            "default": default,
            "minimum": self.minimum,
            "maximum": self.maximum,
            "exclusiveMinimum": self.exclusive_minimum,
            "magnitude": self.magnitude,
            "choices": list(self.choices),
            "unit": self.unit,
            "help": self.help,
        }


def _gain(name: str, help: str, unit: str, *, magnitude: bool = False) -> ControlParameter:
    low, high = GAIN_LIMITS[name]
    return ControlParameter(name, "number", None, help, low, high, magnitude=magnitude, unit=unit)


#: Every parameter of the closed loop, by name.
PARAMETERS: Mapping[str, ControlParameter] = MappingProxyType(
    {
        p.name: p
        for p in (
            _gain("kp", "proportional gain (negative for a plant that cools)", "in/out",
                  magnitude=True),
            _gain("ti", "integral time", "s"),
            _gain("td", "derivative time (0: a PI)", "s"),
            ControlParameter("rule", "choice", "simc", "tuning rule", choices=tuple(RULES)),
            ControlParameter("form", "choice", None, "controller form (default: the rule's "
                             "first)", choices=("pid", "pi")),
            ControlParameter("tau_c", "number", None, "closed-loop time constant of imc and "
                             "simc (default: the model's dead time, or tau/10 without one)",
                             # above a millisecond: a tinier one (5e-324) overflows the gains
                             1e-3, 1e6, exclusive_minimum=True, unit="s"),
            ControlParameter("every", "integer", 50, "adaptive: retune every this many "
                             "samples", 1, 100_000, unit="samples"),
            ControlParameter("max_change", "number", 0.2, "adaptive: largest relative change "
                             "of Kp and Ti per retune", 0.0, 10.0, exclusive_minimum=True),
            ControlParameter("settle_tol", "number", 0.1, "adaptive: retune only if every "
                             "estimate since the last retune stayed within this fraction of "
                             "the latest", 0.0, 1.0, exclusive_minimum=True),
            ControlParameter("excitation", "number", 0.05, "adaptive: retune only if the "
                             "input moved by this fraction of its range since the last retune",
                             0.0, 1.0),
            ControlParameter("kp_range", "range", GAIN_LIMITS["kp"], "adaptive: bounds of |Kp|",
                             *GAIN_LIMITS["kp"], unit="in/out"),
            ControlParameter("ti_range", "range", GAIN_LIMITS["ti"], "adaptive: bounds of Ti",
                             *GAIN_LIMITS["ti"], unit="s"),
            ControlParameter("derivative_filter", "number", 10.0, "N of the derivative filter "
                             "Td/N", 1.0, 1000.0),
        )
    }
)  # fmt: skip


def control_json() -> dict[str, Any]:
    """The parameters and the tuning rules as JSON (the body of ``GET /api/control``).

    Examples
    --------
    >>> body = control_json()
    >>> [p["name"] for p in body["parameters"]][:3], body["rules"][1]["name"]
    (['kp', 'ti', 'td'], 'simc')
    """
    return {
        "parameters": [p.to_json() for p in PARAMETERS.values()],
        "rules": [
            {
                "name": name,
                "title": title,
                "forms": list(RULE_FORMS[name]),
                "speed": name in SPEED_RULES,
            }
            for name, title in RULES.items()
        ],
        "modes": ["manual", "auto"],
    }
