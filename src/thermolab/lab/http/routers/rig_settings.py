"""Routes of a rig's teacher settings: read them, change them (teachers only).

The body's fields and the answer's list are built from the declarations in
:mod:`thermolab.lab.config.teacher_settings`; a value outside the rig's range
is a 422 ``setting_out_of_range`` naming the range, one the rig does not have
(the twin speed-up of hardware or of a rig host's twin) a 422
``setting_not_for_rig``, a save based on an old version a 409 ``settings_changed``.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Request
from pydantic import BaseModel, ConfigDict, Field, create_model

from thermolab.lab.audit.log import AuditAction
from thermolab.lab.config.teacher_settings import TEACHER_SETTINGS, TeacherSetting
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import AUTHENTICATED, LabDep, RigId, UserDep, audit, documented_errors
from thermolab.lab.rigs.rig_settings import RigSettings
from thermolab.lab.service import Lab

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)


def setting_field(setting: TeacherSetting) -> tuple[Any, Any]:
    """A body field of ``setting``: its type from the declaration, left out to keep it."""
    kind: Any
    if setting.type == "choice":
        kind = Literal[setting.choices]
    else:
        kind = Annotated[float, Field(allow_inf_nan=False)]
    if setting.nullable:
        kind = kind | None
    return (kind, Field(default=None, description=setting.help))


class _Values(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


SettingsValuesIn = create_model(  # type: ignore[call-overload]
    "SettingsValuesIn",
    __base__=_Values,
    __doc__="New values by setting name; a setting left out keeps its value.",
    **{s.name: setting_field(s) for s in TEACHER_SETTINGS},
)


class SettingsIn(In):
    """A change of a rig's settings, based on the version last read."""

    version: Annotated[int, Field(ge=1, le=2**31 - 1)]
    values: SettingsValuesIn  # type: ignore[valid-type]


class SettingOut(Out):
    """One setting: its declaration, the range on this rig and its value in force."""

    name: str
    type: Literal["number", "choice"]
    unit: str = Field(description="s, or the rig's input or output unit (input_unit, output_unit)")
    minimum: float | None = Field(description="the least value a teacher may set on this rig")
    maximum: float | None = Field(description="the largest (the technician's cap applied)")
    default: float | str | None
    help: str
    applies: Literal["next_turn", "next_run", "now"]
    choices: list[str]
    nullable: bool
    value: float | str | None


class RigSettingsOut(Out):
    """A rig's teacher settings."""

    rig: str
    version: int
    updated_at: datetime
    updated_by: str | None
    input_unit: str
    output_unit: str
    settings: list[SettingOut]


def _out(lab: Lab, settings: RigSettings) -> RigSettingsOut:
    published = lab.hub.published(settings.rig_id)
    rows = []
    for setting in TEACHER_SETTINGS:
        if setting.name not in settings.values:
            continue  # not this rig's (the twin speed-up of hardware)
        bounds = settings.ranges[setting.name]
        rows.append(
            SettingOut(
                name=setting.name,
                type=setting.type,
                unit=setting.unit,
                minimum=None if bounds is None else bounds[0],
                maximum=None if bounds is None else bounds[1],
                default=setting.default,
                help=setting.help,
                applies=setting.applies,
                choices=list(setting.choices),
                nullable=setting.nullable,
                value=settings.values[setting.name],
            )
        )
    return RigSettingsOut(
        rig=settings.rig_id,
        version=settings.version,
        updated_at=settings.updated_at,
        updated_by=settings.updated_by,
        input_unit=published.input_unit,
        output_unit=published.output_unit,
        settings=rows,
    )


@router.get(
    "/rigs/{rig_id}/settings",
    response_model=RigSettingsOut,
    tags=["settings"],
    summary="A rig's teacher settings",
    responses=documented_errors(403, 404),
)
def get_settings(rig_id: RigId, who: UserDep, lab: LabDep) -> RigSettingsOut:
    """The turn and idle limits, maximum run, cool-down and (a twin the lab runs) speed-up
    in force on the rig, with the range a teacher may set each to (teachers only)."""
    return _out(lab, lab.settings.get(rig_id, who))


@router.put(
    "/rigs/{rig_id}/settings",
    response_model=RigSettingsOut,
    tags=["settings"],
    summary="Change a rig's teacher settings",
    responses=documented_errors(403, 404, 409, 422),
)
def put_settings(
    rig_id: RigId, body: SettingsIn, who: UserDep, lab: LabDep, request: Request
) -> RigSettingsOut:
    """Save some or all settings over ``version`` (409 ``settings_changed`` if someone saved
    since). The turn limit applies from the next turn, the maximum run and the twin speed-up
    from the next run; the turn and the run going keep theirs. A setting the rig does not
    have is a 422 ``setting_not_for_rig``."""
    given: BaseModel = body.values
    values = {name: getattr(given, name) for name in given.model_fields_set}
    saved = _out(lab, lab.settings.update(rig_id, who, values, body.version))
    audit(lab, who, request, AuditAction.RIG_SETTINGS_CHANGED, rig_id, **values)
    return saved
