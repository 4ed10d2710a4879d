"""Teachers' routes of the LTI tool: platforms, keys, roster sync, grade outbox, deep links.

Every route needs a login. Platforms and keys are a lab administrator's; a
teacher synchronises and sees the grades of the courses they teach
(:mod:`thermolab.lab.accounts.policy`); the deep-link picker is its
launcher's.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal
from urllib.parse import parse_qs

import anyio.to_thread
from fastapi import APIRouter, Path, Request, Response, status
from pydantic import Field

from thermolab.errors import InvalidParameterError
from thermolab.lab.accounts.policy import Action
from thermolab.lab.audit.log import AuditAction
from thermolab.lab.http.bodies import In, Out
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    MAX_ROW_ID,
    LabDep,
    UserDep,
    audit,
    documented_errors,
)
from thermolab.lab.http.errors import request_language
from thermolab.lab.http.lti_pages import return_page
from thermolab.lab.lti.grades import GradeInfo
from thermolab.lab.lti.platforms import PlatformInfo

__all__ = ["router"]

router = APIRouter(prefix="/lti", tags=["lti"], **AUTHENTICATED)

PlatformId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="the platform's number")]
GradeId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="the queued grade's number")]
DeepLinkKey = Annotated[
    str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_-]+$", description="a request")
]
CourseName = Annotated[
    str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")
]
_Url = Annotated[str, Field(min_length=1, max_length=1024)]
_Text = Annotated[str, Field(min_length=1, max_length=255)]


class ToolOut(Out):
    """What a platform's administrator enters for this tool."""

    login_url: str
    launch_url: str
    jwks_url: str


class PlatformIn(In):
    """A platform to register: its issuer, the client id it gave the tool, its URLs."""

    issuer: _Url
    client_id: _Text
    auth_login_url: _Url
    token_url: _Url
    jwks_url: _Url
    deployment_ids: Annotated[list[_Text], Field(min_length=1, max_length=50)]


class PlatformOut(Out):
    """A registered platform."""

    id: int
    issuer: str
    client_id: str
    auth_login_url: str
    token_url: str
    jwks_url: str
    deployment_ids: list[str]

    @classmethod
    def of(cls, info: PlatformInfo) -> PlatformOut:
        """The answer of a platform."""
        return cls(
            id=info.id,
            issuer=info.issuer,
            client_id=info.client_id,
            auth_login_url=info.auth_login_url,
            token_url=info.token_url,
            jwks_url=info.jwks_url,
            deployment_ids=list(info.deployment_ids),
        )


class KeyOut(Out):
    """The tool's signing key after a rotation."""

    kid: str


class RosterOut(Out):
    """What a roster sync changed."""

    added: list[str]
    removed: list[str]
    kept: int


class GradeOut(Out):
    """A score in the outbox."""

    id: int
    platform: str
    lineitem_url: str
    sub: str
    score_given: float
    score_maximum: float
    timestamp: datetime
    status: Literal["pending", "sent", "failed"]
    attempts: int
    next_attempt_at: datetime
    last_error: str | None
    sent_at: datetime | None

    @classmethod
    def of(cls, info: GradeInfo) -> GradeOut:
        """The answer of a queued score."""
        return cls(
            id=info.id,
            platform=info.platform,
            lineitem_url=info.lineitem_url,
            sub=info.sub,
            score_given=info.score_given,
            score_maximum=info.score_maximum,
            timestamp=info.timestamp,
            status=info.status.value,
            attempts=info.attempts,
            next_attempt_at=info.next_attempt_at,
            last_error=info.last_error,
            sent_at=info.sent_at,
        )


class LinkItemOut(Out):
    """Something the teacher can place in the LMS course."""

    kind: str
    target: str
    title: str
    rig: str | None


class DeepLinkOut(Out):
    """A deep-linking request: where it goes back to, what can be chosen."""

    platform: str
    accept_multiple: bool
    items: list[LinkItemOut]


@router.get(
    "/tool",
    response_model=ToolOut,
    summary="The tool's URLs for an LMS",
    responses=documented_errors(403),
)
def tool(request: Request, who: UserDep) -> ToolOut:
    """The URLs an LMS administrator enters when adding ThermoLab as an LTI 1.3 tool."""
    who.require_teacher("see the LTI settings")
    return ToolOut(
        login_url=str(request.url_for("lti_login")),
        launch_url=str(request.url_for("lti_launch")),
        jwks_url=str(request.url_for("lti_jwks")),
    )


@router.get(
    "/platforms",
    response_model=list[PlatformOut],
    summary="Registered platforms",
    responses=documented_errors(403),
)
def list_platforms(lab: LabDep, who: UserDep) -> list[PlatformOut]:
    """Every registered LMS (administrators)."""
    lab.authorize.require_lab(who, Action.LTI_PLATFORMS)
    return [PlatformOut.of(p) for p in lab.lti.platforms.list()]


@router.post(
    "/platforms",
    response_model=PlatformOut,
    status_code=status.HTTP_201_CREATED,
    summary="Register a platform",
    responses=documented_errors(403, 409, 422),
)
def register_platform(body: PlatformIn, lab: LabDep, who: UserDep, request: Request) -> PlatformOut:
    """Register an LMS (https URLs; http only on this machine; administrators)."""
    lab.authorize.require_lab(who, Action.LTI_PLATFORMS)
    info = lab.lti.platforms.register(
        issuer=body.issuer,
        client_id=body.client_id,
        auth_login_url=body.auth_login_url,
        token_url=body.token_url,
        jwks_url=body.jwks_url,
        deployment_ids=body.deployment_ids,
    )
    audit(
        lab,
        who,
        request,
        AuditAction.LTI_PLATFORM_ADDED,
        f"{info.issuer} {info.client_id}",
        platform=info.id,
    )
    return PlatformOut.of(info)


@router.delete(
    "/platforms/{platform_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    summary="Remove a platform",
    responses=documented_errors(403, 404),
)
def remove_platform(
    platform_id: PlatformId, lab: LabDep, who: UserDep, request: Request
) -> Response:
    """Remove an LMS (its links to accounts and its queued grades go with it)."""
    lab.authorize.require_lab(who, Action.LTI_PLATFORMS)
    lab.lti.platforms.remove(platform_id)
    audit(lab, who, request, AuditAction.LTI_PLATFORM_REMOVED, str(platform_id))
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.post(
    "/keys/rotate",
    response_model=KeyOut,
    summary="Rotate the tool's key",
    responses=documented_errors(403),
)
def rotate_key(lab: LabDep, who: UserDep, request: Request) -> KeyOut:
    """Make a new signing key; the old one stays published for 7 days (administrators)."""
    lab.authorize.require_lab(who, Action.LTI_PLATFORMS)
    kid = lab.lti.keys.rotate().kid
    audit(lab, who, request, AuditAction.LTI_KEY_ROTATED, kid)
    return KeyOut(kid=kid)


@router.post(
    "/courses/{course}/roster",
    response_model=RosterOut,
    summary="Synchronise a course's roster from the LMS",
    responses=documented_errors(403, 404),
)
def sync_roster(course: CourseName, lab: LabDep, who: UserDep, request: Request) -> RosterOut:
    """Add the LMS course's people to the lab course; remove those who left it."""
    lab.authorize.require_course(who, Action.COURSE_LMS_ROSTER, course)
    report = lab.lti.roster.sync(course)
    audit(
        lab,
        who,
        request,
        AuditAction.LMS_ROSTER_SYNCED,
        course,
        added=list(report.added),
        removed=list(report.removed),
    )
    return RosterOut(added=report.added, removed=report.removed, kept=report.kept)


@router.get(
    "/grades",
    response_model=list[GradeOut],
    summary="The grade outbox",
    responses=documented_errors(403),
)
def list_grades(lab: LabDep, who: UserDep) -> list[GradeOut]:
    """Scores queued for LMS gradebooks, newest first (your courses' students' only)."""
    lab.authorize.require(who, Action.COURSE_LMS_GRADES)
    courses = lab.authorize.taught(who, Action.COURSE_LMS_GRADES)
    return [GradeOut.of(g) for g in lab.lti.grades.list(courses=courses)]


@router.post(
    "/grades/{grade_id}/retry",
    response_model=GradeOut,
    summary="Try a queued score again now",
    responses=documented_errors(403, 404),
)
def retry_grade(grade_id: GradeId, lab: LabDep, who: UserDep, request: Request) -> GradeOut:
    """Make a failed score due again now (with a fresh count of attempts)."""
    lab.authorize.require(who, Action.COURSE_LMS_GRADES)
    courses = lab.authorize.taught(who, Action.COURSE_LMS_GRADES)
    info = GradeOut.of(lab.lti.grades.retry(grade_id, courses=courses))
    audit(lab, who, request, AuditAction.GRADE_RETRIED, str(grade_id), sub=info.sub)
    lab.lti.kick()
    return info


@router.get(
    "/deep-links/{key}",
    response_model=DeepLinkOut,
    summary="A deep-linking request and what it can link",
    responses=documented_errors(404),
)
def deep_link(key: DeepLinkKey, lab: LabDep, who: UserDep) -> DeepLinkOut:
    """The items the teacher who launched the request can choose."""
    pending = lab.lti.deep_links.get(key, who.user_id)
    return DeepLinkOut(
        platform=pending.platform.issuer,
        accept_multiple=pending.settings.get("accept_multiple") is not False,
        items=[
            LinkItemOut(kind=i.kind, target=i.target, title=i.title, rig=i.rig)
            for i in lab.lti.deep_links.items(pending)
        ],
    )


@router.post(
    "/deep-links/{key}",
    summary="Answer a deep-linking request (a page that posts back to the LMS)",
    responses=documented_errors(404, 422),
    openapi_extra={
        "requestBody": {
            "content": {
                "application/x-www-form-urlencoded": {
                    "schema": {"type": "object", "properties": {"target": {"type": "string"}}}
                }
            }
        }
    },
)
async def answer_deep_link(
    key: DeepLinkKey, request: Request, lab: LabDep, who: UserDep
) -> Response:
    """Sign the chosen items (form fields ``target``) and post them back to the LMS."""
    body = await request.body()
    try:
        fields = parse_qs(body.decode("utf-8"), max_num_fields=200)
    except (UnicodeDecodeError, ValueError):
        raise InvalidParameterError("the choice is not a UTF-8 form") from None
    targets = fields.get("target", [])
    if not targets:
        raise InvalidParameterError("choose at least one item to link")
    launch_url = str(request.url_for("lti_launch"))
    return_url, jwt = await anyio.to_thread.run_sync(
        lambda: lab.lti.deep_links.answer(key, who.user_id, targets, launch_url)
    )
    return return_page(return_url, jwt, request_language(request.headers, request.cookies))
