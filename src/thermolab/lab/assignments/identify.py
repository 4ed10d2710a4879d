"""A handed-in run identified again with an assignment's methods, by the library.

Each method is the registry's batch function (:mod:`thermolab.ident.registry`)
run over the stored record with the assignment's settings, exactly as
``thermolab identify`` runs it on an exported file. The library's verdict is
kept as it is: a result is trusted when its model is valid and it carries no
warning (including the warnings the functions raise while they work, as the
command line counts them), and its simulation fit % is reported where the
method computes one. No database here: the caller hands in the samples.
"""

from __future__ import annotations

import inspect
import math
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from thermolab.errors import ThermoLabError
from thermolab.ident.registry import check_settings, get_method
from thermolab.lab.assignments.marking import Identified

__all__ = ["check_methods", "identify_run"]


def check_methods(methods: Sequence[str], settings: Mapping[str, Mapping[str, Any]]) -> None:
    """Refuse unknown methods, or settings a method does not take or allow.

    Raises
    ------
    InvalidParameterError
        With the registry's message (which names what is allowed).
    """
    for method in methods:
        get_method(method)
    for method, given in settings.items():
        if method not in methods:
            get_method(method)  # an unknown name is refused with the list of known ones
            from thermolab.errors import InvalidParameterError

            raise InvalidParameterError(
                f"settings given for {method}, which the assignment does not use"
            )
        check_settings(method, given)


def identify_run(
    method: str,
    t: Sequence[float],
    u: Sequence[float],
    y: Sequence[float],
    dt: float,
    settings: Mapping[str, Any] | None = None,
) -> Identified:
    """Identify a record with one method; a failure is an untrusted result saying why.

    Parameters
    ----------
    method : str
        A registry name.
    t, u, y : sequence of float
        The run's sample times, inputs and outputs.
    dt : float
        The run's sample time.
    settings : mapping, optional
        The method's settings as the teacher set them (checked by the registry).

    Returns
    -------
    Identified
    """
    m = get_method(method)
    given = dict(settings or {})
    check_settings(method, given)
    identify = {k: v for k, v in given.items() if k in m.setting_names("identify")}
    data = {
        "t": np.asarray(t, float),
        "u": np.asarray(u, float),
        "y": np.asarray(y, float),
        "dt": float(dt),
    }
    function = m.batch_function()
    if "t" not in m.data and "t" in inspect.signature(function).parameters:
        identify["t"] = data["t"]  # the sample times: jitter and gaps are flagged
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = function(*(data[name] for name in m.data), **identify)
        except (ThermoLabError, ValueError) as exc:
            return Identified(method, None, None, None, None, False, (str(exc),))
    notes = [str(w) for w in getattr(result, "warnings", ())]
    for w in caught:
        if str(w.message) not in notes:
            notes.append(str(w.message))
    model = result.final if "trajectory" in m.returns else result.model
    fit = getattr(result, "fit_simulation", None)
    return Identified(
        method,
        _finite(model.K),
        _finite(model.tau),
        _finite(getattr(model, "theta", None)),
        _finite(fit),
        bool(model.valid) and not notes,
        tuple(notes),
    )


def _finite(value: Any) -> float | None:
    if value is None:
        return None
    number = float(value)
    return number if math.isfinite(number) else None
