"""How a run's identifiers treat the rig's operating point.

The lab does not judge the rig (no clock, no "time since the last run"): the
operating point is a property of the record, decided from the data by the
library's one procedure (:func:`thermolab.ident.operating_point.decide_operating_point`,
``offset="auto"``). The lab passes the request's ``offset`` to the identifiers;
each method's result then reports the handling used and the operating point
found (its ``extras``). What the lab stores with the run is what was asked,
what the identifiers were given and why (:class:`OperatingPoint`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from thermolab.errors import InvalidParameterError
from thermolab.lab.runs.request import OFFSET_METHODS

__all__ = ["AUTO", "OperatingPoint", "choose_operating_point"]

#: The request's offset that leaves the decision to the data.
AUTO = "auto"


@dataclass(frozen=True, slots=True)
class OperatingPoint:
    """How a run's identifiers handle the operating point, and why (stored with the run).

    Attributes
    ----------
    asked : str or float
        The request's ``offset`` (``"auto"`` unless the user chose).
    used : str, float or None
        The offset the identifiers were built with (``"auto"``: each decides
        from the record and reports it in its result); ``None`` when no chosen
        method regresses on the output (the step response finds its own
        baseline).
    reason : str
        The choice, in words (shown to the user).

    Examples
    --------
    >>> OperatingPoint("fit", "fit", "fit, as asked").to_dict()["used"]
    'fit'
    """

    asked: str | float
    used: str | float | None
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (``asked``, ``used``, ``reason``)."""
        return {"asked": self.asked, "used": self.used, "reason": self.reason}


def choose_operating_point(asked: str | float, methods: Sequence[str]) -> OperatingPoint:
    """Decide what the run's identifiers are given as ``offset``.

    Parameters
    ----------
    asked : str or float
        The request's ``offset``.
    methods : sequence of str
        The run's methods (only LSM, block LSM, MALSM and WLSM use an offset).

    Returns
    -------
    OperatingPoint

    Raises
    ------
    InvalidParameterError
        For an explicit offset when no chosen method uses one.

    Examples
    --------
    >>> choose_operating_point("initial", ["lsm"]).reason
    'initial, as asked'
    >>> choose_operating_point("auto", ["srm"]).used is None
    True
    """
    if not any(m in OFFSET_METHODS for m in methods):
        if asked != AUTO:
            raise InvalidParameterError(
                f"offset is a setting of {', '.join(OFFSET_METHODS)}, none of which is among "
                f"the methods ({', '.join(methods)}); the step response finds its own baseline"
            )
        return OperatingPoint(
            asked, None, "no chosen method uses it (the step response finds its baseline)"
        )
    if asked != AUTO:
        return OperatingPoint(asked, asked, f"{asked}, as asked")
    return OperatingPoint(
        asked,
        AUTO,
        "auto: each method decides from the record (at ambient, settled under an input, "
        "or moving) and reports the handling used and the operating point found",
    )
