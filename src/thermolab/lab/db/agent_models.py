"""The lab's record of its rig hosts (``thermolab agent``): one row per remote rig.

Kept apart from :mod:`.models` (issue #14; that module is at its size limit)
on the same ``Base``: the migrations environment and the engine import this
module so that the metadata is complete.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import ForeignKey, String
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["AgentHost"]


class AgentHost(Base):
    """A rig's host: its secret (SHA-256 of 256 random bits), when it last spoke, its version.

    The secret is stored hashed, like session tokens: a copy of the database
    does not let anyone pose as a rig host.
    """

    __tablename__ = "agent_hosts"

    rig_id: Mapped[str] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"), primary_key=True)
    secret_hash: Mapped[str] = mapped_column(String(64))
    issued_at: Mapped[datetime] = mapped_column(UTCDateTime)
    last_contact: Mapped[datetime | None] = mapped_column(UTCDateTime)
    version: Mapped[str | None] = mapped_column(String(64))
    spec: Mapped[str | None] = mapped_column(String(200))
    fault: Mapped[str | None] = mapped_column(String(500))
