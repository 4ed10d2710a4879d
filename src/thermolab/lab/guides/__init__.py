"""Guide pages per rig: default text shipped in pt-BR and English, edited by teachers.

:mod:`.render` turns Markdown with maths into sanitised HTML (MathML);
:mod:`.service` stores the revisions and falls back to the shipped defaults.
"""

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
    "MAX_MARKDOWN_CHARS",
    "SECTIONS",
    "GuideSection",
    "GuideService",
    "RevisionInfo",
    "default_markdown",
    "render_markdown",
]
