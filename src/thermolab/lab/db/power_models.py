"""The history of a rig's power: one row per change of :attr:`RigRow.power_state`.

The ``rigs`` row holds only the power state now and when it last changed;
how long a rig was powered over a term (class analytics) needs every change.
The access model writes a row wherever it changes the state
(:func:`thermolab.lab.access.queries.write_transition`, and start-up's reset to
off), so the history begins with revision ``0013``: power before it is unknown.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import CheckConstraint, ForeignKey, Index, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, PowerState, UTCDateTime

__all__ = ["PowerChange"]


class PowerChange(Base):
    """A rig's power state from ``at`` until its next change (``off``, ``on``, ``cooling``)."""

    __tablename__ = "rig_power_changes"
    __table_args__ = (
        CheckConstraint(f"state IN ({', '.join(repr(v.value) for v in PowerState)})", name="state"),
        Index("ix_rig_power_changes_rig_id_at", "rig_id", "at"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    rig_id: Mapped[str] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"))
    at: Mapped[datetime] = mapped_column(UTCDateTime)
    state: Mapped[str] = mapped_column(String(16))
