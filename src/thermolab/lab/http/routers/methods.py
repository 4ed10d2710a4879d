"""Route of the identification methods: the registry, as the browser's panels read it.

``GET /api/methods`` is :func:`thermolab.ident.registry.registry_json` plus
``runSettings``: the settings a run request takes with the lab's ranges
(:data:`thermolab.lab.runs.request.RUN_SETTINGS`), so the panels refuse what
the server would.
"""

from __future__ import annotations

from typing import Any, Literal

from fastapi import APIRouter
from pydantic import BaseModel, ConfigDict, Field
from pydantic.alias_generators import to_camel

from thermolab.ident.registry import registry_json
from thermolab.lab.http.deps import AUTHENTICATED
from thermolab.lab.runs.request import RUN_SETTINGS

__all__ = ["MethodOut", "MethodsOut", "SettingOut", "router"]

router = APIRouter(**AUTHENTICATED)


class _Out(BaseModel):
    model_config = ConfigDict(alias_generator=to_camel, populate_by_name=True)


class SettingOut(_Out):
    """One setting of a method, as :class:`thermolab.ident.registry.Setting` declares it."""

    name: str
    type: str
    default: Any = Field(description="null: derived from other settings (see help)")
    minimum: float | None
    maximum: float | None
    exclusive_minimum: bool | None
    exclusive_maximum: bool | None
    choices: list[str] | None
    unit: str | None
    help: str
    role: Literal["identify", "statistics"]


class MethodOut(_Out):
    """One identification method, as :class:`thermolab.ident.registry.Method` declares it."""

    name: str
    title: str
    description: str
    panel: int = Field(description="the paper's panel: 1 SRM/LSM/block LSM, 2 MALSM, 3 WLSM")
    returns: list[Literal["final", "trajectory"]]
    settings: list[SettingOut]


class MethodsOut(_Out):
    """Every identification method, in the paper's order (``registry_json()``), and the
    settings a run request carries with the lab's ranges."""

    methods: list[MethodOut]
    run_settings: list[SettingOut] = Field(
        description="the method settings POST .../runs takes, each as the registry declares "
        "it except where the lab narrows the range (thermolab.lab.runs.request.LAB_NARROWING)"
    )


@router.get(
    "/methods",
    response_model=MethodsOut,
    response_model_by_alias=True,
    tags=["methods"],
    summary="Identification methods and their settings",
)
def list_methods() -> dict[str, Any]:
    """The method registry: names, titles, panels, and each setting's type, default,
    range, unit and help. A run's settings (POST .../runs) take these names; the lab
    narrows a few ranges, which its run schema publishes.
    """
    return {
        **registry_json(),
        "runSettings": [setting.to_json() for setting in RUN_SETTINGS.values()],
    }
