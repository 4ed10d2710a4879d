"""Input checks shared by every identification method.

Each check raises a :mod:`thermolab.errors` exception whose message names the
argument, what was wrong with it and what is allowed, so the command line and
the server can pass it on as it is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

from thermolab.errors import InvalidDataError, InvalidParameterError

from .models import ArxOrder
from .registry import SETTINGS

FloatArray = npt.NDArray[np.float64]

#: The offset mode that decides the operating point from the data
#: (:func:`thermolab.ident.operating_point.decide_operating_point`).
AUTO_OFFSET = "auto"

#: The offset modes a model is fitted with (besides a float, the known ambient
#: output); ``"auto"`` resolves to one of them.
OFFSET_MODES: tuple[str, ...] = tuple(c for c in SETTINGS["offset"].choices if c != AUTO_OFFSET)


def as_signal(name: str, values: npt.ArrayLike) -> FloatArray:
    """``values`` as a finite one-dimensional float array, or an InvalidDataError."""
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidDataError(f"{name} must be an array of numbers: {exc}") from None
    if arr.ndim != 1:
        raise InvalidDataError(f"{name} must be one-dimensional, got shape {arr.shape}")
    finite = np.isfinite(arr)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        raise InvalidDataError(
            f"{name} must be finite (no NaN or inf): {name}[{bad[0]}] is {float(arr[bad[0]])!r} "
            f"({bad.size} bad sample{'s' if bad.size > 1 else ''})"
        )
    return arr


def as_record(u: npt.ArrayLike, y: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Check ``u`` and ``y`` together: finite, one-dimensional, the same length."""
    u_arr = as_signal("u", u)
    y_arr = as_signal("y", y)
    if u_arr.size != y_arr.size:
        raise InvalidDataError(
            f"u and y must have the same number of samples, got {u_arr.size} and {y_arr.size}"
        )
    return u_arr, y_arr


def check_time(t: npt.ArrayLike, n: int | None = None) -> FloatArray:
    """Check a time axis: finite, one-dimensional, strictly increasing, ``n`` samples."""
    return check_time_steps(t, n)[0]


def check_time_steps(t: npt.ArrayLike, n: int | None = None) -> tuple[FloatArray, FloatArray]:
    """:func:`check_time`, also returning the steps ``diff(t)`` it computed."""
    t_arr = as_signal("t", t)
    if n is not None and t_arr.size != n:
        raise InvalidDataError(f"t must have one time per sample ({n}), got {t_arr.size}")
    steps = np.diff(t_arr)
    if steps.size and not (steps > 0.0).all():
        i = int(np.flatnonzero(steps <= 0.0)[0])
        raise InvalidDataError(
            f"t must be strictly increasing: t[{i + 1}] = {float(t_arr[i + 1])!r} follows "
            f"t[{i}] = {float(t_arr[i])!r}"
        )
    return t_arr, steps


def check_dt(dt: object) -> float:
    """The sample period as a float, finite and > 0."""
    v = real("dt", dt)
    if not (math.isfinite(v) and v > 0.0):
        raise InvalidParameterError(f"dt (sample period) must be finite and > 0 seconds, got {v!r}")
    return v


def real(name: str, value: object) -> float:
    """``value`` as a float; booleans and non-numbers are refused."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidParameterError(f"{name} must be a real number, got {value!r}")
    return float(value)


def integer(name: str, value: object, minimum: int, what: str) -> int:
    """``value`` as an int >= ``minimum``; ``what`` explains the lower bound."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InvalidParameterError(f"{name} must be an integer, got {value!r}")
    v = int(value)
    if v < minimum:
        raise InvalidParameterError(f"{name} must be >= {minimum} ({what}), got {v}")
    return v


def check_order(order: object) -> ArxOrder:
    """``None`` (first order), an :class:`ArxOrder`, a ``(na, nb, delay)`` tuple or a dict."""
    if order is None:
        return ArxOrder()
    if isinstance(order, ArxOrder):
        return order
    if isinstance(order, tuple | list) and len(order) == 3:
        return ArxOrder(*order)
    if isinstance(order, Mapping) and set(order) <= {"na", "nb", "delay"}:
        return ArxOrder(**order)
    raise InvalidParameterError(
        "order must be None (first order), an ArxOrder, a (na, nb, delay) tuple or a "
        f"{{'na', 'nb', 'delay'}} dict, got {order!r}"
    )


def check_offset(offset: object) -> str | float:
    """One of :data:`OFFSET_MODES` or a finite float (a known ambient output)."""
    if isinstance(offset, str):
        if offset in OFFSET_MODES:
            return offset
        raise InvalidParameterError(
            f"offset must be one of {', '.join(repr(m) for m in OFFSET_MODES)} or a number "
            f"(the known ambient output in volts), got {offset!r}"
        )
    v = real("offset", offset)
    if not math.isfinite(v):
        raise InvalidParameterError(f"offset (ambient output) must be finite, got {v!r}")
    return v


def check_offset_or_auto(offset: object) -> str | float:
    """``"auto"``, one of :data:`OFFSET_MODES` or a finite float."""
    if offset == AUTO_OFFSET:
        return AUTO_OFFSET
    if isinstance(offset, str) and offset not in OFFSET_MODES:
        raise InvalidParameterError(
            "offset must be one of 'auto' (decided from the data), "
            f"{', '.join(repr(m) for m in OFFSET_MODES)} or a number "
            f"(the known ambient output in volts), got {offset!r}"
        )
    return check_offset(offset)


def check_min_samples(n: int, needed: int, why: str) -> None:
    """Too few samples: say how many are needed and why."""
    if n < needed:
        raise InvalidDataError(f"too few samples: {why} needs at least {needed}, got {n}")


def check_known(method: str, params: Mapping[str, object], allowed: tuple[str, ...]) -> None:
    """Refuse a parameter the method does not take, listing the ones it does."""
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise InvalidParameterError(
            f"unknown parameter{'s' if len(unknown) > 1 else ''} for {method}: "
            f"{', '.join(unknown)}; allowed: {', '.join(allowed) if allowed else 'none'}"
        )
