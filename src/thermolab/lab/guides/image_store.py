"""The guide pages' pictures in the database: upload (teachers), read (anyone logged in).

Pictures are checked and re-encoded by :func:`~thermolab.lab.guides.images.clean_image`
and stored in the table ``guide_images`` (no file on disk, so every worker of
the lab, on SQLite or PostgreSQL, serves them alike). A picture uploaded again
for the same rig is the same row: the upload answers the one already stored.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import NotFoundError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import LabClock
from thermolab.lab.config.model import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.guide_image_models import GuideImage
from thermolab.lab.guides.images import clean_image

__all__ = ["IMAGE_URL", "MAX_ALT_CHARS", "GuideImageService", "ImageData", "ImageInfo"]

IMAGE_URL = "/api/guide-images/{id}"
"""Where a stored picture is served (the guide's Markdown links to it)."""
MAX_ALT_CHARS = 200
"""The longest alternative text of a picture's Markdown snippet."""


@dataclass(frozen=True, slots=True)
class ImageInfo:
    """A stored picture, without its bytes.

    Attributes
    ----------
    id : int
    rig_id : str
    content_type : str
    size, width, height : int
        Bytes; pixels.
    sha256 : str
    uploaded_by : str
    uploaded_at : datetime
    created : bool
        ``False`` where an upload found the same picture already stored.
    """

    id: int
    rig_id: str
    content_type: str
    size: int
    width: int
    height: int
    sha256: str
    uploaded_by: str
    uploaded_at: datetime
    created: bool = False

    @property
    def url(self) -> str:
        """The picture's URL in the lab."""
        return IMAGE_URL.format(id=self.id)

    def markdown(self, alt: str = "") -> str:
        """The Markdown that shows the picture, with ``alt`` as its text (escaped)."""
        text = re.sub(r"\s+", " ", alt).strip()
        text = re.sub(r"([\\\[\]])", r"\\\1", text)
        return f"![{text}]({self.url})"


@dataclass(frozen=True, slots=True)
class ImageData:
    """A stored picture's bytes, as served."""

    data: bytes
    content_type: str
    sha256: str


def _info(row: GuideImage, *, created: bool = False) -> ImageInfo:
    return ImageInfo(
        row.id,
        row.rig_id,
        row.content_type,
        row.size,
        row.width,
        row.height,
        row.sha256,
        row.uploaded_by,
        row.uploaded_at,
        created,
    )


def _same(session: Session, rig_id: str, sha256: str) -> GuideImage | None:
    return session.scalars(
        select(GuideImage).where(GuideImage.rig_id == rig_id, GuideImage.sha256 == sha256)
    ).one_or_none()


class GuideImageService:
    """Store and serve the pictures of each configured rig's guide.

    Parameters
    ----------
    db : Database
    clock : LabClock
    config : LabConfig
        Its rigs are the ones with a guide (others are 404).
    """

    def __init__(self, db: Database, clock: LabClock, config: LabConfig) -> None:
        self.db = db
        self.clock = clock
        self.config = config

    def upload(self, rig_id: str, data: bytes, who: Principal, declared: str | None) -> ImageInfo:
        """Check, clean and store a picture for a rig's guide (teachers only).

        Raises
        ------
        AccessDeniedError
            For a student.
        NotFoundError
            For an unknown rig.
        InvalidParameterError
            The refusals of :func:`~thermolab.lab.guides.images.clean_image`.
        """
        who.require_teacher("add pictures to a guide")
        self.config.rig(rig_id)
        image = clean_image(data, declared)
        now = self.clock.now()
        with self.db.write() as session:
            # The rig's row serialises two uploads of the same picture.
            self.db.lock_rig(session, rig_id)
            found = _same(session, rig_id, image.sha256)
            if found is not None:
                return _info(found)
            row = GuideImage(
                rig_id=rig_id,
                content_type=image.content_type,
                data=image.data,
                size=len(image.data),
                width=image.width,
                height=image.height,
                sha256=image.sha256,
                uploaded_by=who.username,
                uploaded_at=now,
            )
            session.add(row)
            session.flush()
            return _info(row, created=True)

    def of_rig(self, rig_id: str, who: Principal) -> list[ImageInfo]:
        """A rig's pictures, newest first (teachers only, to reuse one)."""
        who.require_teacher("see a guide's pictures")
        self.config.rig(rig_id)
        with self.db.read() as session:
            rows = session.scalars(
                select(GuideImage).where(GuideImage.rig_id == rig_id).order_by(GuideImage.id.desc())
            ).all()
            return [_info(row) for row in rows]

    def get(self, image_id: int) -> ImageData:
        """A picture's bytes (anyone logged in: whoever may read the guide).

        Raises
        ------
        NotFoundError
            No such picture.
        """
        with self.db.read() as session:
            row = session.get(GuideImage, image_id)
            if row is None:
                raise NotFoundError(f"no guide picture {image_id}")
            return ImageData(row.data, row.content_type, row.sha256)
