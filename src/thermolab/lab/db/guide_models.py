"""The rigs' guides as teachers edited them: a page per section and language, its revisions.

The pictures in them are :mod:`.guide_image_models`; the guides themselves,
:mod:`thermolab.lab.guides`.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import ForeignKey, Integer, String, Text, UniqueConstraint
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["GuidePage", "GuideRevision"]


class GuidePage(Base):
    """One section of a rig's guide in one language, as teachers edited it.

    The text is the newest of its :class:`GuideRevision` rows; a section no
    teacher has edited has no row (the package's default is shown).
    """

    __tablename__ = "guide_pages"
    __table_args__ = (UniqueConstraint("rig_id", "lang", "section"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    rig_id: Mapped[str] = mapped_column(String(64))
    lang: Mapped[str] = mapped_column(String(8))
    section: Mapped[str] = mapped_column(String(32))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)


class GuideRevision(Base):
    """A guide section's text as one teacher saved it; never changed, never deleted.

    Restoring an older revision adds a new one with its text (``restored_from``
    names it), so the history stays a line.
    """

    __tablename__ = "guide_revisions"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    page_id: Mapped[int] = mapped_column(
        ForeignKey("guide_pages.id", ondelete="CASCADE"), index=True
    )
    markdown: Mapped[str] = mapped_column(Text)
    author: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)
    restored_from: Mapped[int | None] = mapped_column(Integer)
