"""The text syntax of the signals, shared by the command line and the server.

:func:`parse_signal` reads it (the forms are listed in :mod:`thermolab.signals`);
each signal's ``spec`` writes it. Re-exported by :mod:`thermolab.signals`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from thermolab.errors import InvalidParameterError, SignalSpecError

from ._base import DEFAULT_LIMITS, Signal, check_limits
from ._prbs import PRBS
from ._waves import Constant, Sine, Square, Step

__all__ = ["SIGNAL_SYNTAX", "parse_signal"]

#: The accepted forms of a signal specification, as shown in error messages.
SIGNAL_SYNTAX = (
    "const:U, step:U0:U1@T, square:LOW:HIGH:FREQ_HZ, sine:OFFSET:AMPLITUDE:FREQ_HZ, "
    "prbs:LOW:HIGH:BIT_SECONDS[:SEED]"
)

_Fail = Callable[[str], SignalSpecError]


def parse_signal(spec: str, limits: tuple[float, float] = DEFAULT_LIMITS) -> Signal:
    """Parse a signal specification (see the module notes for the syntax).

    Parameters
    ----------
    spec : str
        ``const:U``, ``step:U0:U1@T``, ``square:LOW:HIGH:FREQ_HZ``,
        ``sine:OFFSET:AMPLITUDE:FREQ_HZ`` or ``prbs:LOW:HIGH:BIT_SECONDS[:SEED]``;
        volts, seconds and hertz. The kind is case-insensitive and spaces around
        fields are ignored.
    limits : tuple of float, optional
        The input range; levels outside it are refused. Default ±10 V.

    Returns
    -------
    Signal
        A :class:`Constant`, :class:`Step`, :class:`Square`, :class:`Sine` or
        :class:`PRBS`, whose ``spec`` is the canonical form of ``spec``.

    Raises
    ------
    SignalSpecError
        Naming exactly what is wrong and listing the accepted forms.

    Examples
    --------
    >>> parse_signal("square:4:6:0.1")
    Square(limits=(-10.0, 10.0), low=4.0, high=6.0, freq_hz=0.1)
    >>> parse_signal(" STEP : 0 : 10.0 @ 1 ").spec
    'step:0:10@1'
    >>> parse_signal("prbs:0:4:5").spec
    'prbs:0:4:5:0'
    >>> parse_signal("square:4:6")
    Traceback (most recent call last):
    ...
    thermolab.errors.SignalSpecError: invalid signal 'square:4:6': square needs 3 values \
LOW:HIGH:FREQ_HZ, got 2; accepted forms: ...
    """
    if not isinstance(spec, str):
        raise SignalSpecError(
            f"a signal specification must be text, got {type(spec).__name__}; "
            f"accepted forms: {SIGNAL_SYNTAX}"
        )
    try:
        lo, hi = check_limits(limits)
    except InvalidParameterError as exc:
        raise SignalSpecError(str(exc)) from None

    def fail(problem: str) -> SignalSpecError:
        return SignalSpecError(
            f"invalid signal {spec!r}: {problem}; accepted forms: {SIGNAL_SYNTAX}"
        )

    kind, sep, rest = spec.strip().partition(":")
    kind = kind.strip().lower()
    if not sep or not kind:
        raise fail("expected KIND:VALUES")
    fields = [f.strip() for f in rest.split(":")]
    try:
        if kind == "const":
            (u,) = _fields(fields, 1, "U", kind, fail)
            return Constant(_float(u, "U", fail), limits=(lo, hi))
        if kind == "step":
            if len(fields) != 2 or fields[1].count("@") != 1:
                raise fail("step needs U0:U1@T (the step time after '@')")
            u1_text, _, t_text = fields[1].partition("@")
            return Step(
                _float(fields[0], "U0", fail),
                _float(u1_text.strip(), "U1", fail),
                _float(t_text.strip(), "T", fail),
                limits=(lo, hi),
            )
        if kind == "square":
            low, high, freq = _fields(fields, 3, "LOW:HIGH:FREQ_HZ", kind, fail)
            return Square(
                _float(low, "LOW", fail),
                _float(high, "HIGH", fail),
                _float(freq, "FREQ_HZ", fail),
                limits=(lo, hi),
            )
        if kind == "sine":
            off, amp, freq = _fields(fields, 3, "OFFSET:AMPLITUDE:FREQ_HZ", kind, fail)
            return Sine(
                _float(off, "OFFSET", fail),
                _float(amp, "AMPLITUDE", fail),
                _float(freq, "FREQ_HZ", fail),
                limits=(lo, hi),
            )
        if kind == "prbs":
            if len(fields) not in (3, 4):
                raise fail(
                    f"prbs needs 3 or 4 values LOW:HIGH:BIT_SECONDS[:SEED], got {len(fields)}"
                )
            seed = 0
            if len(fields) == 4:
                if not (fields[3].isascii() and fields[3].isdigit()):
                    raise fail(f"SEED must be a non-negative integer, got {fields[3]!r}")
                seed = int(fields[3])
            return PRBS(
                _float(fields[0], "LOW", fail),
                _float(fields[1], "HIGH", fail),
                _float(fields[2], "BIT_SECONDS", fail),
                seed,
                limits=(lo, hi),
            )
    except SignalSpecError:
        raise
    except InvalidParameterError as exc:
        raise fail(str(exc)) from None
    raise fail(f"unknown kind {kind!r}")


def _fields(fields: list[str], n: int, names: str, kind: str, fail: _Fail) -> list[str]:
    if len(fields) != n:
        plural = "value" if n == 1 else "values"
        raise fail(f"{kind} needs {n} {plural} {names}, got {len(fields)}")
    return fields


def _float(text: str, name: str, fail: _Fail) -> float:
    try:
        # float() would also take '1_0' and 'infinity'; accept plain decimal numbers only.
        if not text or "_" in text:
            raise ValueError
        value = float(text)
    except ValueError:
        raise fail(f"{name} must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise fail(f"{name} must be finite, got {text!r}")
    return value
