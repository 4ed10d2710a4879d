"""A handed-in run identified again with an assignment's methods, by the library.

Each method is the registry's batch function (:mod:`thermolab.ident.registry`)
run over the stored record with the assignment's settings, exactly as
``thermolab identify`` runs it on an exported file (:func:`thermolab.ident.assess.assess`,
one function for both): the library's verdict is kept as it is (the free-run fit,
agreement with the output-error fit, convergence: not a warning-free result,
which real kits never give), and its simulation fit % is reported where the
method computes one. No database here: the caller hands in the samples.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from thermolab.errors import ThermoLabError
from thermolab.ident.assess import assess
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
    units: tuple[str, str] | None = None,
    peers: dict[str, dict[str, Any]] | None = None,
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
    units : (str, str), optional
        The rig's input and output units: the library's words speak of them.
    peers : dict, optional
        The run's output-error fits, shared by its methods' verdicts (one per run).

    Returns
    -------
    Identified
    """
    given = dict(settings or {})
    check_settings(method, given)
    try:
        assessment = assess(method, t, u, y, float(dt), given, units=units, peers=peers)
    except (ThermoLabError, ValueError) as exc:
        return Identified(method, None, None, None, None, False, (str(exc),))
    s, verdict = assessment.summary, assessment.verdict
    return Identified(
        method,
        _finite(s.get("K")),
        _finite(s.get("tau")),
        _finite(s.get("theta")),
        _finite(getattr(assessment.result, "fit_simulation", None)),
        verdict.trusted,
        verdict.reasons + verdict.notes,
    )


def _finite(value: Any) -> float | None:
    if value is None:
        return None
    number = float(value)
    return number if math.isfinite(number) else None
