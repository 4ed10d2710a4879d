"""Routes of a course's limits: read them, replace them (teachers of the course).

During the course's booked slot on a rig, the values given here replace the
rig's teacher settings there (each lowered to the rig's technician cap); a
setting left out keeps the rig's value, and outside slots the rig's are in
force (:mod:`thermolab.lab.classes.course_settings`). The body's fields are built from
the declarations in :mod:`thermolab.lab.config.teacher_settings`
(``COURSE_SETTINGS``); a value outside its range is a 422
``setting_out_of_range``, a save based on an old version a 409 ``settings_changed``.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from fastapi import APIRouter
from pydantic import BaseModel, Field, create_model

from thermolab.lab.classes.course_settings import CourseSettings, ranges
from thermolab.lab.config.teacher_settings import COURSE_SETTINGS
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import AUTHENTICATED, LabDep, UserDep, documented_errors
from thermolab.lab.http.routers.courses import CourseName
from thermolab.lab.http.routers.rig_settings import setting_field

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)

#: The rule, as the API and the course page say it.
RULE = (
    "During the course's booked slot on a rig these values replace the rig's (lowered to the "
    "rig's cap); a setting left out, and every rig outside the course's slots, keeps the rig's. "
    "A turn keeps the time limit it started with."
)


class _Values(BaseModel):
    model_config = {"extra": "forbid", "strict": True}


CourseValuesIn = create_model(  # type: ignore[call-overload]
    "CourseValuesIn",
    __base__=_Values,
    __doc__="The course's values by setting name; a setting left out keeps the rig's.",
    **{s.name: setting_field(s) for s in COURSE_SETTINGS},
)


class CourseSettingsIn(In):
    """The course's new overrides (all of them), based on the version last read."""

    version: Annotated[int, Field(ge=0, le=2**31 - 1)]
    values: CourseValuesIn  # type: ignore[valid-type]


class CourseSettingOut(Out):
    """One setting a course may override, with the course's value if it gives one."""

    name: str
    unit: str
    minimum: float | None = Field(description="the least value (a rig's cap may lower the most)")
    maximum: float | None
    help: str
    applies: Literal["next_turn", "next_run", "now"]
    nullable: bool
    overridden: bool = Field(description="false: the rig's value is in force in the slots")
    value: float | str | None


class CourseSettingsOut(Out):
    """A course's overrides of the rigs' limits during its slots."""

    course: str
    version: int = Field(description="0: never saved")
    updated_at: datetime | None
    updated_by: str | None
    rule: str
    settings: list[CourseSettingOut]


def _out(settings: CourseSettings) -> CourseSettingsOut:
    bounds = ranges()
    rows = []
    for setting in COURSE_SETTINGS:
        low_high = bounds[setting.name]
        rows.append(
            CourseSettingOut(
                name=setting.name,
                unit=setting.unit,
                minimum=None if low_high is None else low_high[0],
                maximum=None if low_high is None else low_high[1],
                help=setting.help,
                applies=setting.applies,
                nullable=setting.nullable,
                overridden=setting.name in settings.values,
                value=settings.values.get(setting.name),
            )
        )
    return CourseSettingsOut(
        course=settings.course,
        version=settings.version,
        updated_at=settings.updated_at,
        updated_by=settings.updated_by,
        rule=RULE,
        settings=rows,
    )


@router.get(
    "/courses/{course}/settings",
    response_model=CourseSettingsOut,
    tags=["settings"],
    summary="A course's limits during its slots",
    responses=documented_errors(403, 404, 422),
)
def get_course_settings(course: CourseName, who: UserDep, lab: LabDep) -> CourseSettingsOut:
    """The turn limit, idle limit and longest run the course sets on its booked rigs during
    its slots (teachers of the course only)."""
    return _out(lab.course_settings.get(course, who))


@router.put(
    "/courses/{course}/settings",
    response_model=CourseSettingsOut,
    tags=["settings"],
    summary="Replace a course's limits during its slots",
    responses=documented_errors(403, 404, 409, 422),
)
def put_course_settings(
    course: CourseName, body: CourseSettingsIn, who: UserDep, lab: LabDep
) -> CourseSettingsOut:
    """Replace the course's values over ``version`` (409 ``settings_changed`` if someone saved
    since); a setting left out keeps the rig's value. The turn limit applies from the next
    turn, the longest run from the next START; the turn and the run going keep theirs."""
    given: BaseModel = body.values
    values = {name: getattr(given, name) for name in given.model_fields_set}
    return _out(lab.course_settings.update(course, who, values, body.version))
