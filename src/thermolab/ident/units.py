"""The methods' messages in a record's units: they speak of volts, the paper's rig's.

A record in % and °C should not read "V" anywhere: :func:`in_units` rewrites a
message, :func:`error_in_units` an exception, and
:func:`thermolab.ident.assess.assess` applies them to every warning, reason and
refusal it gives for a record whose units it is told.
"""

from __future__ import annotations

import re

__all__ = ["error_in_units", "in_units"]

_INPUT_WORDS = ("input", "under", "kept at", "stays at", "u[0]", "held", "step of")
_OUTPUT_WORDS = ("output", "ambient", "y[0]", "noise", "rms", "±", "it changes", "changed by")
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
