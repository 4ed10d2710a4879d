"""Limits per course: a course overrides the rigs' limits during its booked slots.

The rule (one, so that the turn rules are never ambiguous): during a course's
booked slot on a rig, the course's values of the settings it overrides
(``COURSE_SETTINGS``: turn limit, idle limit, longest run) are in force on that
rig, each lowered to the rig's technician cap; outside slots, and for a setting
the course leaves out, the rig's teacher settings are. A turn keeps the time
limit in force when it started (its deadline is set then); the idle limit is
read at every check, the longest run at START. The turn rules read a course's
values with its slots (:func:`thermolab.lab.access.queries.read_slots`).

Only a teacher of the course changes them (403 for anyone else); a save names
the version it was based on (409 ``settings_changed`` after another save); a
value outside the declared range is a 422 ``setting_out_of_range``.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from thermolab.errors import SettingsChangedError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.classes.closed import require_open
from thermolab.lab.classes.course_access import course_named, require_member
from thermolab.lab.clock import LabClock
from thermolab.lab.config.teacher_settings import (
    COURSE_SETTINGS,
    SettingValue,
    allowed_range,
    check_value,
)
from thermolab.lab.db import Database
from thermolab.lab.db.course_settings_models import CourseSettingsRow
from thermolab.lab.db.models import Course, Role

__all__ = ["CourseSettings", "CourseSettingsService"]

_NAMES = {s.name: s for s in COURSE_SETTINGS}


@dataclass(frozen=True, slots=True)
class CourseSettings:
    """A course's overrides.

    Attributes
    ----------
    course : str
    values : dict
        Setting name -> the course's value; a name left out keeps the rig's.
    version : int
        Counts the saves (0: never saved).
    updated_at : datetime or None
    updated_by : str or None
    """

    course: str
    values: dict[str, SettingValue]
    version: int
    updated_at: datetime | None
    updated_by: str | None


def ranges() -> dict[str, tuple[float, float] | None]:
    """The declared range of each setting a course may override (a rig's cap lowers it there)."""
    return {s.name: allowed_range(s, {}, None) for s in COURSE_SETTINGS}


class CourseSettingsService:
    """Reads and saves a course's overrides (teachers of the course)."""

    def __init__(self, db: Database, clock: LabClock) -> None:
        self._db = db
        self._clock = clock
        self._lock = threading.Lock()

    def _course(self, session: Session, name: str, who: Principal, action: str) -> Course:
        who.require_teacher(action)
        course = course_named(session, name)
        require_member(session, course, who, Role.TEACHER, action)
        return course

    def get(self, name: str, who: Principal) -> CourseSettings:
        """A course's overrides (teachers of the course).

        Raises
        ------
        AccessDeniedError
            For a student or a teacher not in the course.
        NotFoundError
            For an unknown course.
        """
        with self._db.read() as session:
            course = self._course(session, name, who, "see a course's limits")
            row = session.get(CourseSettingsRow, course.id)
            return _settings(course.name, row)

    def update(
        self, name: str, who: Principal, values: Mapping[str, object], version: int
    ) -> CourseSettings:
        """Replace the course's overrides by ``values`` over version ``version``.

        A setting left out of ``values`` keeps the rig's value during the slots.

        Raises
        ------
        AccessDeniedError, NotFoundError
            As :meth:`get`.
        SettingRangeError
            A value outside its declared range; nothing is saved.
        SettingsChangedError
            The overrides were saved since ``version``.
        """
        bounds = ranges()
        checked = {n: check_value(_NAMES[n], v, bounds[n]) for n, v in values.items()}
        with self._lock, self._db.write() as session:
            course = self._course(session, name, who, "change a course's limits")
            require_open(course, "change its limits")
            row = session.get(CourseSettingsRow, course.id, with_for_update=True)
            current = 0 if row is None else row.version
            if version != current:
                raise SettingsChangedError(
                    f"the limits of course {course.name!r} were saved since version {version} "
                    f"(now {current}); load them again and repeat the change"
                )
            now = self._clock.now()
            if row is None:
                row = CourseSettingsRow(course_id=course.id, version=0)
                session.add(row)
            row.values = checked
            row.version = current + 1
            row.updated_at = now
            row.updated_by = who.username
            try:
                session.flush()
            except IntegrityError as exc:  # another lab saved the first version meanwhile
                raise SettingsChangedError(
                    f"the limits of course {course.name!r} were saved meanwhile; load them "
                    "again and repeat the change"
                ) from exc
            return _settings(course.name, row)


def _settings(course: str, row: CourseSettingsRow | None) -> CourseSettings:
    if row is None:
        return CourseSettings(course, {}, 0, None, None)
    values = {k: v for k, v in row.values.items() if k in _NAMES}
    return CourseSettings(course, values, row.version, row.updated_at, row.updated_by)
