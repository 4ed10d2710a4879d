"""Guide pages per rig: default text shipped in pt-BR and English, edited by teachers.

:mod:`.render` turns Markdown with maths into sanitised HTML (MathML);
:mod:`.service` stores the revisions and falls back to the shipped defaults;
:mod:`.images` checks and re-encodes uploaded pictures (Pillow), which
:mod:`.image_store` keeps in the database.
"""

from thermolab.lab.guides.image_store import (
    IMAGE_URL,
    MAX_ALT_CHARS,
    GuideImageService,
    ImageData,
    ImageInfo,
)
from thermolab.lab.guides.images import IMAGE_TYPES, MAX_IMAGE_BYTES, MAX_IMAGE_PIXELS
from thermolab.lab.guides.render import MAX_MARKDOWN_CHARS, render_markdown
from thermolab.lab.guides.service import (
    FALLBACK_LANGUAGE,
    GUIDE_LANGUAGES,
    SECTIONS,
    GuideSection,
    GuideService,
    RevisionInfo,
    default_markdown,
)

__all__ = [
    "FALLBACK_LANGUAGE",
    "GUIDE_LANGUAGES",
    "IMAGE_TYPES",
    "IMAGE_URL",
    "MAX_ALT_CHARS",
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_PIXELS",
    "MAX_MARKDOWN_CHARS",
    "SECTIONS",
    "GuideImageService",
    "GuideSection",
    "GuideService",
    "ImageData",
    "ImageInfo",
    "RevisionInfo",
    "default_markdown",
    "render_markdown",
]
