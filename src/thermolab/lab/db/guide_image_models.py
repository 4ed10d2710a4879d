"""Pictures of the guide pages (:mod:`thermolab.lab.guides.image_store`), in the database.

Each row is one picture as the lab re-encoded it (no metadata), for the rig
whose guide it was uploaded for; the same picture is stored once per rig
(``sha256`` of the stored bytes). Rows are never changed, so an image's URL
can be cached for good.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import Integer, LargeBinary, String, UniqueConstraint
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["GuideImage"]


class GuideImage(Base):
    """A picture a teacher uploaded for a rig's guide."""

    __tablename__ = "guide_images"
    __table_args__ = (UniqueConstraint("rig_id", "sha256"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    rig_id: Mapped[str] = mapped_column(String(64))
    content_type: Mapped[str] = mapped_column(String(32))
    data: Mapped[bytes] = mapped_column(LargeBinary)
    size: Mapped[int] = mapped_column(Integer)
    width: Mapped[int] = mapped_column(Integer)
    height: Mapped[int] = mapped_column(Integer)
    sha256: Mapped[str] = mapped_column(String(64))
    uploaded_by: Mapped[str] = mapped_column(String(64))
    uploaded_at: Mapped[datetime] = mapped_column(UTCDateTime)
