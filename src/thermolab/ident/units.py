"""The methods' messages in a record's units: they speak of volts, the paper's rig's.

A record in % and °C should not read "V" anywhere: :func:`in_units` rewrites a
message, :func:`error_in_units` an exception, and
:func:`thermolab.ident.assess.assess` applies them to every warning, reason and
refusal it gives for a record whose units it is told.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = ["error_in_units", "in_units", "in_units_everywhere"]

_INPUT_WORDS = ("input", "under", "kept at", "stays at", "u[0]", "held", "step of")
_OUTPUT_WORDS = ("output", "ambient", "y[0]", "noise", "rms", "±", "it changes", "changed by")
_SHOWN = {"degC": "°C"}
"""Units as a rig declares them -> as a person reads them."""
_VOLTS = re.compile(r"(?P<num>[-+]?\d[\d.]*(?:e[-+]?\d+)?) V\b")


def in_units(text: str, u_unit: str, y_unit: str) -> str:
    """A method's message with its volts in the record's units (input or output, by context).

    The methods speak of volts (the paper's rig); a record in % and °C should
    not read "V". Each number followed by ``V`` takes the unit of the signal
    named nearest before it.

    Examples
    --------
    >>> in_units("small step: the input changes by 0.5 V; the output moves 2 V", "%", "°C")
    'small step: the input changes by 0.5 %; the output moves 2 °C'
    """
    if u_unit == "V" and y_unit == "V":
        return text
    u_unit, y_unit = _SHOWN.get(u_unit, u_unit), _SHOWN.get(y_unit, y_unit)

    def unit(m: re.Match[str]) -> str:
        before = text[: m.start()].lower()
        last_in = max(before.rfind(w) for w in _INPUT_WORDS)
        last_out = max(before.rfind(w) for w in _OUTPUT_WORDS)
        chosen = u_unit if last_in > last_out else y_unit
        return m.group("num") + (f" {chosen}" if chosen else "")

    out = _VOLTS.sub(unit, text)
    return out.replace("in volts", "in the record's units").replace("of volts", "")


def error_in_units(exc: Exception, u_unit: str, y_unit: str) -> Exception:
    """``exc`` again, its message in the record's units (the same type, for the exit status)."""
    text = in_units(str(exc), u_unit, y_unit)
    if text == str(exc):
        return exc
    try:
        return type(exc)(text)
    except TypeError:
        return exc


def in_units_everywhere(value: Any, u_unit: str, y_unit: str) -> Any:
    """``value`` with every string in it (in dicts and lists, at any depth) :func:`in_units`.

    For a result as it is stored or sent (its warnings, reasons, operating
    point), whose words the methods wrote in volts.

    Examples
    --------
    >>> in_units_everywhere({"warnings": ["small step: the input changes by 0.5 V"],
    ...                      "K": 0.6}, "%", "°C")
    {'warnings': ['small step: the input changes by 0.5 %'], 'K': 0.6}
    """
    if u_unit == "V" and y_unit == "V":
        return value  # the methods' own words: nothing to walk (a run's arrays included)
    if isinstance(value, str):
        return in_units(value, u_unit, y_unit)
    if isinstance(value, dict):
        return {k: in_units_everywhere(v, u_unit, y_unit) for k, v in value.items()}
    if isinstance(value, list):
        return [in_units_everywhere(v, u_unit, y_unit) for v in value]
    return value
