"""Routes of the guide pages of each rig: read, edit (teachers), revisions, restore, preview.

``GET /api/rigs/{rig}/guide?lang=`` gives every section, rendered and
sanitised on the server (:mod:`thermolab.lab.guides`); without ``lang`` the
reader's language (cookie, then ``Accept-Language``).
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from fastapi import APIRouter, Path, Query, Request
from pydantic import Field

from thermolab.errors import AccessDeniedError
from thermolab.lab.guides import MAX_MARKDOWN_CHARS, GuideSection, RevisionInfo, render_markdown
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    MAX_ROW_ID,
    LabDep,
    RigId,
    UserDep,
    documented_errors,
)
from thermolab.lab.http.errors import request_language

__all__ = ["router"]

router = APIRouter(**AUTHENTICATED)

Language = Literal["pt-BR", "en", "es"]
Section = Literal["introduction", "theory", "panel-1", "panel-2", "panel-3", "panel-4", "school"]
LangQuery = Annotated[
    Language | None,
    Query(description="the guide's language (default: the reader's: cookie, Accept-Language)"),
]
SectionPath = Annotated[Section, Path(description="a section of the guide")]
RevisionId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="a revision's number")]


class SectionOut(Out):
    """One section: its Markdown, its sanitised HTML, and who saved it when."""

    section: Section
    lang: Language = Field(description="the text's language (en where es has none)")
    markdown: str
    html: str = Field(description="sanitised HTML, maths as MathML")
    revision_id: int | None = Field(description="null: the lab's shipped default")
    author: str | None
    saved_at: datetime | None

    @classmethod
    def of(cls, section: GuideSection) -> SectionOut:
        """Build from a :class:`~thermolab.lab.guides.GuideSection`."""
        return cls(
            section=section.section,  # type: ignore[arg-type]
            lang=section.lang,  # type: ignore[arg-type]
            markdown=section.markdown,
            html=section.html,
            revision_id=section.revision_id,
            author=section.author,
            saved_at=section.saved_at,
        )


class GuideOut(Out):
    """A rig's guide in one language: every section in reading order."""

    rig: str
    lang: Language
    sections: list[SectionOut]


class RevisionOut(Out):
    """A saved revision (``markdown`` and ``html`` only when one revision is asked for)."""

    id: int
    section: Section
    lang: Language
    author: str
    saved_at: datetime
    restored_from: int | None
    markdown: str | None = None
    html: str | None = None

    @classmethod
    def of(cls, info: RevisionInfo) -> RevisionOut:
        """Build from a :class:`~thermolab.lab.guides.RevisionInfo`."""
        return cls(
            id=info.id,
            section=info.section,  # type: ignore[arg-type]
            lang=info.lang,  # type: ignore[arg-type]
            author=info.author,
            saved_at=info.saved_at,
            restored_from=info.restored_from,
            markdown=info.markdown,
            html=info.html,
        )


class MarkdownIn(In):
    """A section's new text."""

    markdown: str = Field(max_length=MAX_MARKDOWN_CHARS, description="Markdown, $…$ maths")


class PreviewOut(Out):
    """The sanitised HTML a text would show."""

    html: str


def _language(lang: Language | None, request: Request) -> Language:
    chosen = lang or request_language(request.headers, request.cookies)
    return chosen  # type: ignore[return-value]


@router.get(
    "/rigs/{rig_id}/guide",
    response_model=GuideOut,
    tags=["guides"],
    summary="A rig's guide",
    responses=documented_errors(404),
)
def read_guide(rig_id: RigId, request: Request, lab: LabDep, lang: LangQuery = None) -> GuideOut:
    """Every section of the rig's guide: a teacher's newest revision, else the lab's default."""
    chosen = _language(lang, request)
    sections = lab.guides.guide(rig_id, chosen)
    return GuideOut(rig=rig_id, lang=chosen, sections=[SectionOut.of(s) for s in sections])


@router.put(
    "/rigs/{rig_id}/guide/{section}",
    response_model=SectionOut,
    tags=["guides"],
    summary="Edit a section of a rig's guide",
    responses=documented_errors(403, 404, 422),
)
def edit_section(
    rig_id: RigId,
    section: SectionPath,
    body: MarkdownIn,
    request: Request,
    who: UserDep,
    lab: LabDep,
    lang: LangQuery = None,
) -> SectionOut:
    """Save a section's new text as its newest revision (teachers only)."""
    saved = lab.guides.save(rig_id, _language(lang, request), section, body.markdown, who)
    return SectionOut.of(saved)


@router.get(
    "/rigs/{rig_id}/guide/{section}/revisions",
    response_model=list[RevisionOut],
    tags=["guides"],
    summary="A section's revisions",
    responses=documented_errors(403, 404),
)
def list_revisions(
    rig_id: RigId,
    section: SectionPath,
    request: Request,
    who: UserDep,
    lab: LabDep,
    lang: LangQuery = None,
) -> list[RevisionOut]:
    """Who saved the section when, newest first (teachers only)."""
    infos = lab.guides.revisions(rig_id, _language(lang, request), section, who)
    return [RevisionOut.of(info) for info in infos]


@router.get(
    "/rigs/{rig_id}/guide-revisions/{revision_id}",
    response_model=RevisionOut,
    tags=["guides"],
    summary="One revision with its text",
    responses=documented_errors(403, 404),
)
def read_revision(rig_id: RigId, revision_id: RevisionId, who: UserDep, lab: LabDep) -> RevisionOut:
    """An older revision's text and HTML, to view before restoring it (teachers only)."""
    return RevisionOut.of(lab.guides.revision(rig_id, revision_id, who))


@router.post(
    "/rigs/{rig_id}/guide-revisions/{revision_id}/restore",
    response_model=SectionOut,
    tags=["guides"],
    summary="Restore an older revision",
    responses=documented_errors(403, 404),
)
def restore_revision(
    rig_id: RigId, revision_id: RevisionId, who: UserDep, lab: LabDep
) -> SectionOut:
    """Save an older revision's text again as the newest (teachers only)."""
    return SectionOut.of(lab.guides.restore(rig_id, revision_id, who))


@router.post(
    "/guide-preview",
    response_model=PreviewOut,
    tags=["guides"],
    summary="Preview Markdown as a guide shows it",
    responses=documented_errors(403, 422),
)
def preview(body: MarkdownIn, who: UserDep) -> PreviewOut:
    """The sanitised HTML of a text, as the editor's preview shows it (teachers only)."""
    if not who.is_teacher:
        raise AccessDeniedError("only a teacher may edit a guide")
    return PreviewOut(html=render_markdown(body.markdown))
