"""The teacher settings of each rig (:mod:`thermolab.lab.rigs.rig_settings`), one row per rig.

The values are one JSON object keyed by the names declared in
:mod:`thermolab.lab.config.teacher_settings` (a column per setting would declare
each a second time); ``version`` counts the saves, for optimistic concurrency.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["RigSettingsRow"]


class RigSettingsRow(Base):
    """A rig's teacher settings as last saved (seeded from the lab's file at first start)."""

    __tablename__ = "rig_settings"

    rig_id: Mapped[str] = mapped_column(String(64), primary_key=True)
    values: Mapped[dict[str, Any]] = mapped_column(JSON)
    version: Mapped[int] = mapped_column(Integer)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime)
    updated_by: Mapped[str | None] = mapped_column(String(64))
