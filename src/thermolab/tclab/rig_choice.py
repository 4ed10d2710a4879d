"""Which lab rig a ``TCLab`` drives, and whether it can: the default pick and the kit check.

A rig is kit-like when its input is a heater in % and its output a
temperature; the rig comes from ``rig=``, else ``THERMOLAB_RIG``, else
:func:`pick_rig`.
"""

from __future__ import annotations

from typing import Any

from thermolab.client import LabRequestError
from thermolab.tclab.kit_errors import NotAKitError

__all__ = ["ENV_RIG", "TEMPERATURE_UNITS", "check_kit", "describe_rig", "kit_like", "pick_rig"]

ENV_RIG = "THERMOLAB_RIG"

TEMPERATURE_UNITS = frozenset({"°C", "degC", "C", "ºC"})
"""Output units ``T1`` reads as a temperature in °C."""


def kit_like(rig: dict[str, Any]) -> bool:
    """A heater in % and a temperature sensor: what ``TCLab`` can drive."""
    return bool(rig["input"]["unit"] == "%" and rig.get("outputUnit") in TEMPERATURE_UNITS)


def pick_rig(rigs: list[dict[str, Any]], simulated: bool | None) -> str:
    """The default rig: the first kit, else the first kit-like rig, else the first rig.

    ``simulated=True`` (``setup(connected=False)``): the first kit-like twin, else
    the first twin.
    """
    if not rigs:
        raise LabRequestError("GET", "/api/rigs", None, "no_rigs", "the lab has no rigs")
    if simulated is True:
        twins = [r for r in rigs if r["kind"] == "sim"]
        heated = [r for r in twins if kit_like(r)]
        if not twins:
            raise LabRequestError(
                "GET",
                "/api/rigs",
                None,
                "no_twin",
                "the lab has no simulated rig for connected=False",
            )
        return str((heated or twins)[0]["id"])
    kits = [r for r in rigs if r["kind"] == "tclab"]
    alike = [r for r in rigs if kit_like(r)]
    return str((kits or alike or rigs)[0]["id"])


def describe_rig(info: dict[str, Any]) -> str:
    """What a rig has, in a user's words: ``rig 'box' (The box): input u 0–10 V, output y in V``."""
    inp = info["input"]
    return (
        f"rig {info['id']!r} ({info.get('title') or info['kind']}) has one input "
        f"(from {inp['min']:g} to {inp['max']:g} {inp['unit']}) and one output "
        f"(in {info.get('outputUnit') or '?'})"
    )


def check_kit(info: dict[str, Any]) -> None:
    """Raise :class:`~thermolab.tclab.NotAKitError` unless the rig is kit-like."""
    unit_in, unit_out = info["input"]["unit"], info.get("outputUnit")
    if not kit_like(info):
        raise NotAKitError(
            f"{describe_rig(info)}: TCLab needs a heater in % and a temperature sensor in °C, so "
            f"T1 would read {unit_out} as °C and Q1 would set {unit_in} as %. Use a TCLab rig "
            "(or the kit's twin, spec sim:tclab), or drive this rig with thermolab.client.Lab"
        )
