"""A course's overrides of the rigs' limits, by course.

Read and written by :mod:`thermolab.lab.classes.course_settings`.

The values are one JSON object keyed by the names of the settings a course may
override (``COURSE_SETTINGS`` in :mod:`thermolab.lab.config.teacher_settings`);
a name left out keeps the rig's value. ``version`` counts the saves.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, ForeignKey, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["CourseSettingsRow"]


class CourseSettingsRow(Base):
    """A course's limits in force on its booked rigs during its slots."""

    __tablename__ = "course_settings"

    course_id: Mapped[int] = mapped_column(
        ForeignKey("courses.id", ondelete="CASCADE"), primary_key=True
    )
    values: Mapped[dict[str, Any]] = mapped_column(JSON)
    version: Mapped[int] = mapped_column(Integer)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime)
    updated_by: Mapped[str | None] = mapped_column(String(64))
