"""Routes of an LTI 1.3 launch: ``/api/lti/login``, ``/launch``, ``/continue``, ``/jwks``.

The LMS (not the lab's pages) sends the browser here, so the login and the
launch are cross-site form posts (``BrowserGuard`` lets these two paths
through: a platform's signed ``id_token`` and the single-use state
authenticate them, never a cookie), and their answers are redirects or
pages (:mod:`~thermolab.lab.http.lti_pages`).

**Cookies and frames.** The LMS shows the tool in an iframe, where today's
browsers send a cookie only if it is ``SameSite=None; Secure`` and
third-party cookies are allowed, or if it is partitioned (CHIPS). The state
cookie of the login and the session cookie of the launch are both
``HttpOnly; Secure; SameSite=None; Partitioned``: in the frame they live in
the LMS's partition, in a new window in the lab's own. (Chromium treats
``http://localhost`` and ``http://127.0.0.1`` as secure, so the tests' http
works.) When the launch arrives without the state cookie — cookies blocked
in the frame — the launch is still checked against the server-side,
single-use state and the signed nonce, and the page offers a link that opens
the lab in a new window, where a one-time ticket (2 minutes) signs the
person in with a first-party cookie.
"""

from __future__ import annotations

import logging
from typing import Annotated, Any
from urllib.parse import parse_qs

import anyio.to_thread
from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import JSONResponse, RedirectResponse
from starlette.requests import HTTPConnection

from thermolab.lab.accounts.users import UserInfo
from thermolab.lab.http.deps import COOKIE_NAME, client_address, documented_errors
from thermolab.lab.http.errors import fault_of, request_language
from thermolab.lab.http.lti_pages import error_page, handover_page
from thermolab.lab.lti.claims import DEEP_LINKING_REQUEST
from thermolab.lab.lti.deep_linking import TARGET_PARAMETER, target_path
from thermolab.lab.lti.errors import LtiError, LtiFormTooLargeError, LtiStateError
from thermolab.lab.lti.launch import LaunchOutcome
from thermolab.lab.service import Lab

__all__ = ["LTI_CROSS_SITE_PATHS", "STATE_COOKIE", "router", "too_large_page"]

router = APIRouter(prefix="/lti", tags=["lti"])
log = logging.getLogger(__name__)

STATE_COOKIE = "thermolab_lti_state"
LTI_CROSS_SITE_PATHS = ("/api/lti/login", "/api/lti/launch")
_MAX_FORM = 64 * 1024
_MAX_FIELDS = 50  # a login or launch form has a handful
_FORM_BODY: dict[str, Any] = {
    "requestBody": {
        "content": {
            "application/x-www-form-urlencoded": {
                "schema": {"type": "object", "additionalProperties": {"type": "string"}}
            }
        }
    }
}


def _lab(request: Request) -> Lab:
    lab: Lab = request.app.state.lab
    return lab


async def _form(request: Request) -> dict[str, str]:
    """The request's query and url-encoded form fields, first value of each."""
    fields = dict(request.query_params.items())
    if request.method == "POST":
        body = await request.body()
        if len(body) > _MAX_FORM:
            raise LtiFormTooLargeError(f"the LMS's form is over {_MAX_FORM} bytes")
        try:
            text = body.decode("utf-8")
        except UnicodeDecodeError:
            raise LtiError("the LMS's form is not UTF-8") from None
        try:
            parsed = parse_qs(text, max_num_fields=_MAX_FIELDS)
        except ValueError:  # the standard library's refusal of more fields
            raise LtiError(f"the LMS's form has too many fields (over {_MAX_FIELDS})") from None
        for key, values in parsed.items():
            fields[key] = values[0]
    if any("\x00" in v or len(v) > _MAX_FORM for v in fields.values()):
        raise LtiError("the LMS's form has a NUL character or a value too long")
    return fields


def _cookie(name: str, value: str, max_age: int, path: str) -> str:
    return (
        f"{name}={value}; Max-Age={max_age}; Path={path}; HttpOnly; Secure; "
        "SameSite=None; Partitioned"
    )


def _refused(request: Request, exc: LtiError) -> Response:
    fault = fault_of(exc)
    language = request_language(request.headers, request.cookies)
    address = client_address(request)
    log.warning("LTI %s refused (%s) from %s: %s", request.url.path, fault.code, address, exc)
    return error_page(fault.code, str(exc), fault.status, language)


def too_large_page(connection: HTTPConnection, size: int, limit: int) -> Response:
    """The LTI error page for a login or launch form over the body limit (logged as a refusal)."""
    address = connection.client.host if connection.client is not None else "unknown"
    detail = f"the LMS's form is over {limit} bytes (at least {size} sent)"
    log.warning(
        "LTI %s refused (lti_form_too_large) from %s: %s", connection.url.path, address, detail
    )
    language = request_language(connection.headers, connection.cookies)
    return error_page("lti_form_too_large", detail, 413, language)


def _need(fields: dict[str, str], name: str) -> str:
    value = fields.get(name)
    if not value:
        raise LtiError(f"the LMS did not send {name!r}")
    return value


_LOGIN_REFUSED: dict[int | str, dict[str, Any]] = {
    400: {"description": "a page saying why the login was refused"},
    **documented_errors(422),
}


@router.get(
    "/login",
    name="lti_login",
    summary="LTI 1.3 login initiation (OIDC third party, by a link)",
    response_class=RedirectResponse,
    status_code=302,
    responses=_LOGIN_REFUSED,
)
async def lti_login(request: Request) -> Response:
    """Store a state and nonce, set the state cookie, send the browser to the platform."""
    return await _login(request)


@router.post(
    "/login",
    summary="LTI 1.3 login initiation (OIDC third party, by a form)",
    response_class=RedirectResponse,
    status_code=302,
    openapi_extra=_FORM_BODY,
    responses=_LOGIN_REFUSED,
)
async def lti_login_form(request: Request) -> Response:
    """The same as the GET, with the parameters in a form."""
    return await _login(request)


async def _login(request: Request) -> Response:
    lab = _lab(request)
    try:
        lab.lti.launches.initiations.check(client_address(request))
        fields = await _form(request)
        redirect = await anyio.to_thread.run_sync(
            lambda: lab.lti.launches.begin(
                issuer=_need(fields, "iss"),
                login_hint=_need(fields, "login_hint"),
                target_link_uri=_need(fields, "target_link_uri"),
                redirect_uri=str(request.url_for("lti_launch")),
                lti_message_hint=fields.get("lti_message_hint"),
                client_id=fields.get("client_id"),
                tool_origin=str(request.base_url),
            )
        )
    except LtiError as exc:
        return _refused(request, exc)
    response = RedirectResponse(redirect.url, status_code=302)
    response.headers.append("Set-Cookie", _cookie(STATE_COOKIE, redirect.state, 600, "/api/lti"))
    return response


@router.post(
    "/launch",
    name="lti_launch",
    summary="LTI 1.3 launch (the platform's id_token)",
    response_class=RedirectResponse,
    status_code=303,
    openapi_extra=_FORM_BODY,
    responses={
        400: {"description": "a page saying why the launch was refused"},
        **documented_errors(422),
    },
)
async def lti_launch(request: Request) -> Response:
    """Check the launch, sign the person in, open the linked page (or the picker)."""
    lab = _lab(request)
    browser_state = request.cookies.get(STATE_COOKIE)
    try:
        fields = await _form(request)
        token, state = _need(fields, "id_token"), _need(fields, "state")
        outcome = await anyio.to_thread.run_sync(
            lambda: lab.lti.launches.complete(
                token, state, browser_state, tool_origin=str(request.base_url)
            )
        )
    except LtiError as exc:
        return _refused(request, exc)
    path = await anyio.to_thread.run_sync(lambda: _destination(lab, outcome))
    if browser_state is None:
        ticket = lab.lti.hand_over(outcome, path)
        url = str(request.url_for("lti_continue").include_query_params(ticket=ticket))
        return handover_page(url, request_language(request.headers, request.cookies))
    return await anyio.to_thread.run_sync(
        lambda: _signed_in(lab, request, outcome.user, path, partitioned=True)
    )


def _destination(lab: Lab, outcome: LaunchOutcome) -> str:
    if outcome.message_type == DEEP_LINKING_REQUEST and outcome.deep_linking is not None:
        key = lab.lti.deep_links.open(
            outcome.user.id,
            outcome.platform,
            outcome.deployment_id,
            outcome.deep_linking,
            outcome.course,
        )
        return f"/#/lti/deep-link/{key}"
    return target_path(outcome.custom.get(TARGET_PARAMETER))


def _signed_in(
    lab: Lab, request: Request, user: UserInfo, path: str, *, partitioned: bool
) -> Response:
    address = request.client.host if request.client is not None else None
    lab.sessions.end(request.cookies.get(COOKIE_NAME))  # whoever was signed in here before
    token, _ = lab.sessions.create(
        user, client_address=address, user_agent=request.headers.get("user-agent")
    )
    response = RedirectResponse(path, status_code=303)
    lifetime = int(lab.config.access.session_lifetime)
    if partitioned:
        response.headers.append("Set-Cookie", _cookie(COOKIE_NAME, token, lifetime, "/"))
        response.headers.append("Set-Cookie", _cookie(STATE_COOKIE, "", 0, "/api/lti"))
    else:
        response.set_cookie(
            COOKIE_NAME,
            token,
            max_age=lifetime,
            path="/",
            httponly=True,
            samesite="lax",  # reached from the LMS by a link: a top-level navigation
            secure=request.url.scheme == "https" or lab.config.access.cookie_secure == "always",
        )
    return response


@router.get(
    "/continue",
    name="lti_continue",
    summary="Open a launch in a new window (cookies blocked in the LMS's frame)",
    response_class=RedirectResponse,
    status_code=303,
    responses={
        400: {"description": "a page saying the ticket is unknown or used"},
        **documented_errors(422),
    },
)
def lti_continue(
    request: Request,
    ticket: Annotated[str, Query(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_-]+$")],
) -> Response:
    """Exchange a one-time ticket for a first-party login, then open the linked page."""
    lab = _lab(request)
    found = lab.lti.take_over(ticket)
    if found is None:
        return _refused(request, LtiStateError("this link was used already or has expired"))
    user, path = found
    return _signed_in(lab, request, user, path, partitioned=False)


@router.get("/jwks", summary="The tool's public keys (JWKS)")
def lti_jwks(request: Request) -> JSONResponse:
    """The tool's public keys, for platforms to check its signatures."""
    return JSONResponse(_lab(request).lti.keys.jwks())
