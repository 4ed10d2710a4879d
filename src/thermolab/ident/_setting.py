"""The type of one declared setting: :class:`Setting` (type, default, range, unit, help).

The declarations themselves, and the methods that take them, are in
:mod:`thermolab.ident.registry`, which re-exports these names. Like the
registry, this module imports nothing heavy.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from thermolab.errors import InvalidParameterError

__all__ = ["Role", "Setting", "SettingType"]

#: How a setting's value is written. ``arx_order`` is ``(na, nb, delay)``;
#: ``offset`` is one of the choices or a number (a known ambient output);
#: ``covariance`` is a number (times the identity) or a matrix.
SettingType = Literal[
    "number", "integer", "choice", "number_list", "arx_order", "offset", "covariance"
]
#: ``identify``: passed to the identifier; ``statistics``: shapes the summary of
#: a trajectory (statistics, convergence), never seen by the identifier.
Role = Literal["identify", "statistics"]

_NO_CHOICES: tuple[str, ...] = ()


@dataclass(frozen=True)
class Setting:
    """One setting of one or more methods: its type, default, range, unit and help.

    Parameters
    ----------
    name : str
        The keyword in the library, the JSON key, and (with ``--``) the CLI option.
    type : SettingType
        How a value is written (see :data:`SettingType`).
    default : object
        The value used when the setting is not given; ``None`` means "derived
        from the other settings", which ``help`` explains.
    help : str
        One line for option help and form tooltips.
    minimum, maximum : float or None, optional
        Bounds of a number or integer (or of each entry of a list).
    exclusive_minimum, exclusive_maximum : bool, optional
        True when the bound itself is not allowed.
    choices : tuple of str, optional
        The allowed words of a ``choice`` (and the words an ``offset`` accepts).
    unit : str or None, optional
        Unit of the value (``"s"``, ``"V"``, ``"samples"``).
    role : {"identify", "statistics"}, optional
        See :data:`Role`.
    metavar : str or None, optional
        How the command line shows the value (``"NA,NB,DELAY"``).
    structural_default : callable or None, optional
        ``(n_dynamic, n_params) -> value`` when the value used by default depends
        on the model structure (``w0``); ``default`` is then the value for the
        paper's first-order model, shown to users.

    Examples
    --------
    >>> from thermolab.ident.registry import SETTINGS
    >>> SETTINGS["gamma"].allowed()
    'a finite number > 0 and <= 1'
    >>> SETTINGS["gamma"].check(1.5)
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: gamma = 1.5 is out of range; allowed: a finite ...
    """

    name: str
    type: SettingType
    default: Any
    help: str
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    exclusive_maximum: bool = False
    choices: tuple[str, ...] = _NO_CHOICES
    unit: str | None = None
    role: Role = "identify"
    metavar: str | None = None
    structural_default: Callable[[int, int], Any] | None = field(
        default=None, compare=False, repr=False
    )

    def allowed(self) -> str:
        """What the setting accepts, in words (used by every error message).

        Examples
        --------
        >>> from thermolab.ident.registry import SETTINGS
        >>> SETTINGS["window"].allowed(), SETTINGS["form"].allowed()
        ('an integer >= 3', 'one of paper, standard')
        """
        if self.type == "choice":
            return "one of " + ", ".join(self.choices)
        if self.type == "offset":
            return "one of " + ", ".join(self.choices) + " or a finite number of volts"
        if self.type == "arx_order":
            return "(na, nb, delay) with na >= 1, nb >= 1, delay >= 0"
        bounds = []
        if self.minimum is not None:
            bounds.append(f"{'>' if self.exclusive_minimum else '>='} {self.minimum:g}")
        if self.maximum is not None:
            bounds.append(f"{'<' if self.exclusive_maximum else '<='} {self.maximum:g}")
        what = {
            "integer": "an integer",
            "number_list": "a list of finite numbers",
            "covariance": "a finite number",
        }.get(self.type, "a finite number")
        if self.type == "number_list" and bounds:
            what += ", each"
        if bounds:
            what += " " + " and ".join(bounds)
        if self.type == "covariance":
            what += " (or, in the library, a symmetric positive-definite matrix)"
        return what

    def in_range(self, value: float) -> bool:
        """True when ``value`` is within ``minimum``/``maximum``.

        Examples
        --------
        >>> from thermolab.ident.registry import SETTINGS
        >>> SETTINGS["pmax"].in_range(0.0), SETTINGS["pmax"].in_range(1e3)
        (False, True)
        """
        if not math.isfinite(value):
            return False
        low, high = self.minimum, self.maximum
        if low is not None and (value < low or (self.exclusive_minimum and value == low)):
            return False
        return not (
            high is not None and (value > high or (self.exclusive_maximum and value == high))
        )

    def check(self, value: Any) -> Any:
        """``value`` checked against the declaration, in its plain Python form.

        ``None`` stands for the default and is returned as it is. Orders,
        offsets and matrices are checked for their shape by the implementation
        (which knows the ARX structure); numbers, integers, choices and lists
        are checked here.

        Raises
        ------
        InvalidParameterError
            Naming the setting, the value and what is allowed.
        """
        if value is None:
            return None
        if self.type == "choice":
            if isinstance(value, str) and value in self.choices:
                return value
            raise self._refuse(value)
        if self.type == "integer":
            if isinstance(value, bool) or not isinstance(value, numbers.Integral):
                raise self._refuse(value)
            if not self.in_range(int(value)):
                raise self._refuse(value, "is out of range")
            return int(value)
        if self.type == "number" or (self.type == "covariance" and _is_real(value)):
            if not _is_real(value):
                raise self._refuse(value)
            if not self.in_range(float(value)):
                raise self._refuse(value, "is out of range")
            return float(value)
        if self.type == "number_list":
            if isinstance(value, str | bytes | Mapping) or not hasattr(value, "__iter__"):
                raise self._refuse(value)
            items = list(value)
            if not all(_is_real(v) and self.in_range(float(v)) for v in items):
                raise self._refuse(value)
            return [float(v) for v in items]
        return value  # arx_order, offset, a covariance matrix: the implementation checks

    def _refuse(self, value: Any, what: str = "is not allowed") -> InvalidParameterError:
        shown = value.tolist() if hasattr(value, "tolist") else value
        return InvalidParameterError(f"{self.name} = {shown!r} {what}; allowed: {self.allowed()}")

    def to_json(self) -> dict[str, Any]:
        """This setting as ``registry_json()`` lists it (camelCase keys, null where n/a)."""
        ranged = self.type in ("number", "integer", "number_list", "covariance")
        default = self.default
        if isinstance(default, tuple):
            default = list(default)
        return {
            "name": self.name,
            "type": self.type,
            "default": default,
            "minimum": self.minimum,
            "maximum": self.maximum,
            "exclusiveMinimum": self.exclusive_minimum if ranged else None,
            "exclusiveMaximum": self.exclusive_maximum if ranged else None,
            "choices": list(self.choices) if self.choices else None,
            "unit": self.unit,
            "help": self.help,
            "role": self.role,
        }


def _is_real(value: Any) -> bool:
    if isinstance(value, bool):
        return False
    return isinstance(value, numbers.Real) and math.isfinite(float(value))
