"""Guide pages per rig: the shipped defaults, teachers' revisions, restore.

A rig's guide has the sections of :data:`SECTIONS` (introduction, theory, the
steps of panels 1–4, school). Each section, in each language of
:data:`GUIDE_LANGUAGES`, is the newest revision a teacher saved, or else the
default shipped in ``defaults/<lang>/<section>.md`` (Portuguese (Brazil),
English and Spanish, each naming the buttons as that language's page labels
them). A language without shipped text would be shown in English, marked so
(``lang`` of the section differs from the one asked). Revisions are never
changed or deleted; restoring one saves its text again as the newest, naming
the one restored.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from functools import lru_cache
from importlib import resources

from sqlalchemy import select
from sqlalchemy.orm import Session

from thermolab.errors import AccessDeniedError, InvalidParameterError, NotFoundError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import LabClock
from thermolab.lab.config.model import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.guide_models import GuidePage, GuideRevision
from thermolab.lab.guides.render import MAX_MARKDOWN_CHARS, render_markdown

__all__ = [
    "FALLBACK_LANGUAGE",
    "GUIDE_LANGUAGES",
    "SECTIONS",
    "GuideSection",
    "GuideService",
    "RevisionInfo",
    "default_markdown",
]

SECTIONS = ("introduction", "theory", "panel-1", "panel-2", "panel-3", "panel-4", "school")
"""A guide's sections, in reading order; ``panel-N`` is the steps of the rig page's panel N."""
GUIDE_LANGUAGES = ("pt-BR", "en", "es")
FALLBACK_LANGUAGE = "en"
# The languages with shipped text, and their folder.
_SHIPPED = {"pt-BR": "pt_BR", "en": "en", "es": "es"}


@lru_cache(maxsize=32)
def default_markdown(lang: str, section: str) -> str | None:
    """The shipped default text of a section, or ``None`` for a language without one."""
    folder = _SHIPPED.get(lang)
    if folder is None:
        return None
    text = resources.files("thermolab.lab.guides").joinpath("defaults", folder, f"{section}.md")
    return text.read_text(encoding="utf-8")


@lru_cache(maxsize=512)
def _html(markdown: str) -> str:
    return render_markdown(markdown)


@dataclass(frozen=True, slots=True)
class GuideSection:
    """One section as a reader gets it.

    Attributes
    ----------
    section : str
    lang : str
        The language of the text (English where Spanish was asked and none was written).
    markdown, html : str
        The source and its sanitised HTML.
    revision_id : int or None
        ``None`` for the shipped default.
    author : str or None
    saved_at : datetime or None
    """

    section: str
    lang: str
    markdown: str
    html: str
    revision_id: int | None
    author: str | None
    saved_at: datetime | None


@dataclass(frozen=True, slots=True)
class RevisionInfo:
    """One saved revision of a section (the text only where asked for)."""

    id: int
    section: str
    lang: str
    author: str
    saved_at: datetime
    restored_from: int | None
    markdown: str | None = None
    html: str | None = None


def _check_section(section: str, lang: str) -> None:
    if section not in SECTIONS:
        raise InvalidParameterError(f"no guide section {section!r}; allowed: {', '.join(SECTIONS)}")
    if lang not in GUIDE_LANGUAGES:
        raise InvalidParameterError(
            f"no guide language {lang!r}; allowed: {', '.join(GUIDE_LANGUAGES)}"
        )


def _newest(session: Session, rig_id: str, lang: str) -> dict[str, GuideRevision]:
    rows = session.execute(
        select(GuidePage.section, GuideRevision)
        .join(GuideRevision, GuideRevision.page_id == GuidePage.id)
        .where(GuidePage.rig_id == rig_id, GuidePage.lang == lang)
        .order_by(GuideRevision.id)
    ).all()
    return {row[0]: row[1] for row in rows}  # the last (newest) of each section wins


class GuideService:
    """Read, edit and restore the guide of each configured rig.

    Parameters
    ----------
    db : Database
    clock : LabClock
    config : LabConfig
        Its rigs are the ones that have a guide (others are 404).
    """

    def __init__(self, db: Database, clock: LabClock, config: LabConfig) -> None:
        self.db = db
        self.clock = clock
        self.config = config

    def guide(self, rig_id: str, lang: str) -> list[GuideSection]:
        """Every section of a rig's guide in ``lang`` (anyone logged in may read).

        Raises
        ------
        NotFoundError
            For an unknown rig.
        InvalidParameterError
            For a language the guides do not have.
        """
        self.config.rig(rig_id)
        _check_section(SECTIONS[0], lang)
        with self.db.read() as session:
            edited = _newest(session, rig_id, lang)
            fallback = _newest(session, rig_id, FALLBACK_LANGUAGE) if lang not in _SHIPPED else {}
        sections = []
        for section in SECTIONS:
            revision = edited.get(section)
            text_lang = lang
            if revision is None and lang not in _SHIPPED:
                revision, text_lang = fallback.get(section), FALLBACK_LANGUAGE
            if revision is not None:
                markdown = revision.markdown
                sections.append(
                    GuideSection(
                        section,
                        text_lang,
                        markdown,
                        _html(markdown),
                        revision.id,
                        revision.author,
                        revision.created_at,
                    )
                )
                continue
            shipped = default_markdown(text_lang, section) or ""
            sections.append(
                GuideSection(section, text_lang, shipped, _html(shipped), None, None, None)
            )
        return sections

    def section(self, rig_id: str, lang: str, section: str) -> GuideSection:
        """One section of :meth:`guide`."""
        _check_section(section, lang)
        return next(s for s in self.guide(rig_id, lang) if s.section == section)

    def save(
        self,
        rig_id: str,
        lang: str,
        section: str,
        markdown: str,
        who: Principal,
        *,
        restored_from: int | None = None,
    ) -> GuideSection:
        """Save a section's new text as its newest revision (teachers only).

        Raises
        ------
        AccessDeniedError
            For a student.
        InvalidParameterError
            Unknown section or language, or a text longer than
            :data:`~thermolab.lab.guides.render.MAX_MARKDOWN_CHARS`.
        NotFoundError
            For an unknown rig.
        """
        who.require_teacher("edit a guide")
        self.config.rig(rig_id)
        _check_section(section, lang)
        if len(markdown) > MAX_MARKDOWN_CHARS:
            raise InvalidParameterError(
                f"a guide section may have at most {MAX_MARKDOWN_CHARS} characters "
                f"(this one has {len(markdown)})"
            )
        now = self.clock.now()
        with self.db.write() as session:
            # The rig's row serialises two teachers saving the same rig's first revision.
            self.db.lock_rig(session, rig_id)
            page = session.scalars(
                select(GuidePage).where(
                    GuidePage.rig_id == rig_id,
                    GuidePage.lang == lang,
                    GuidePage.section == section,
                )
            ).one_or_none()
            if page is None:
                page = GuidePage(rig_id=rig_id, lang=lang, section=section, created_at=now)
                session.add(page)
                session.flush()
            revision = GuideRevision(
                page_id=page.id,
                markdown=markdown,
                author=who.username,
                created_at=now,
                restored_from=restored_from,
            )
            session.add(revision)
            session.flush()
            revision_id = revision.id
        return GuideSection(
            section, lang, markdown, _html(markdown), revision_id, who.username, now
        )

    def revisions(self, rig_id: str, lang: str, section: str, who: Principal) -> list[RevisionInfo]:
        """A section's saved revisions, newest first (teachers only; no text)."""
        who.require_teacher("see a guide's revisions")
        self.config.rig(rig_id)
        _check_section(section, lang)
        with self.db.read() as session:
            rows = session.scalars(
                select(GuideRevision)
                .join(GuidePage, GuideRevision.page_id == GuidePage.id)
                .where(
                    GuidePage.rig_id == rig_id,
                    GuidePage.lang == lang,
                    GuidePage.section == section,
                )
                .order_by(GuideRevision.id.desc())
            ).all()
        return [
            RevisionInfo(row.id, section, lang, row.author, row.created_at, row.restored_from)
            for row in rows
        ]

    def revision(self, rig_id: str, revision_id: int, who: Principal) -> RevisionInfo:
        """One revision with its text and HTML (teachers only).

        Raises
        ------
        NotFoundError
            No such revision of this rig's guide.
        """
        who.require_teacher("see a guide's revisions")
        self.config.rig(rig_id)
        with self.db.read() as session:
            found = session.execute(
                select(GuideRevision, GuidePage)
                .join(GuidePage, GuideRevision.page_id == GuidePage.id)
                .where(GuideRevision.id == revision_id, GuidePage.rig_id == rig_id)
            ).one_or_none()
        if found is None:
            raise NotFoundError(f"no revision {revision_id} of the guide of rig {rig_id!r}")
        row, page = found
        return RevisionInfo(
            row.id,
            page.section,
            page.lang,
            row.author,
            row.created_at,
            row.restored_from,
            row.markdown,
            _html(row.markdown),
        )

    def restore(self, rig_id: str, revision_id: int, who: Principal) -> GuideSection:
        """Make an older revision's text the newest again (a new revision; teachers only)."""
        old = self.revision(rig_id, revision_id, who)
        assert old.markdown is not None  # revision() always reads the text
        return self.save(rig_id, old.lang, old.section, old.markdown, who, restored_from=old.id)


def _require_teacher(who: Principal, what: str) -> None:
    if not who.is_teacher:
        raise AccessDeniedError(f"only a teacher may {what}")
