"""Routes of the login session: ``/api/session`` (log in, who am I, log out)."""

from __future__ import annotations

import logging

from fastapi import APIRouter, Request, Response, status

from thermolab.lab.accounts.names import username_form
from thermolab.lab.accounts.security import AuthenticationError, RateLimitedError
from thermolab.lab.http.account_schemas import CredentialsIn, SessionOut
from thermolab.lab.http.deps import (
    AUTHENTICATED,
    COOKIE_NAME,
    LabDep,
    UserDep,
    documented_errors,
)

__all__ = ["router"]

router = APIRouter()
log = logging.getLogger(__name__)
_authed = AUTHENTICATED


@router.post(
    "/session",
    response_model=SessionOut,
    tags=["session"],
    summary="Log in",
    responses=documented_errors(401, 422, 429),
)
def login(body: CredentialsIn, request: Request, response: Response, lab: LabDep) -> SessionOut:
    """Check the user name and password and open a session (sets the session cookie).

    Failed attempts delay further ones per (user name, client address), and
    attempts are limited per client address (429 with Retry-After); the
    client address is the proxy's ``X-Forwarded-For`` only when the request
    came from an address listed in ``access.trusted_proxies``.
    """
    address = request.client.host if request.client is not None else "unknown"
    key = username_form(body.username)
    try:
        lab.throttle.check(key, address)
    except RateLimitedError:
        log.warning("login delayed: user %r from %s (too many attempts)", key[:64], address)
        raise
    try:
        user = lab.users.verify(body.username, body.password)
    except AuthenticationError:
        lab.throttle.record(key, address, success=False)
        # ASVS V7.2.1: a failed login is attributable (name and address; never the password).
        log.warning("login failed: user %r from %s", key[:64], address)
        raise
    lab.throttle.record(key, address, success=True)
    lab.sessions.end(request.cookies.get(COOKIE_NAME))
    token, principal = lab.sessions.create(
        user, client_address=address, user_agent=request.headers.get("user-agent")
    )
    policy = lab.config.access
    secure = policy.cookie_secure == "always" or (
        policy.cookie_secure == "auto" and request.url.scheme == "https"
    )
    response.set_cookie(
        COOKIE_NAME,
        token,
        max_age=int(policy.session_lifetime),
        path="/",
        httponly=True,
        samesite=policy.cookie_samesite,
        secure=secure,
    )
    return SessionOut.of(principal, lab.names.names([principal.username]).get(principal.username))


@router.get(
    "/session",
    response_model=SessionOut,
    tags=["session"],
    summary="Who am I",
    **_authed,
)
def whoami(who: UserDep, lab: LabDep) -> SessionOut:
    """Return the logged-in user."""
    return SessionOut.of(who, lab.names.names([who.username]).get(who.username))


@router.delete(
    "/session",
    status_code=status.HTTP_204_NO_CONTENT,
    tags=["session"],
    summary="Log out",
    **_authed,
)
def logout(request: Request, lab: LabDep) -> Response:
    """End the session and clear its cookie."""
    lab.sessions.end(request.cookies.get(COOKIE_NAME))
    response = Response(status_code=status.HTTP_204_NO_CONTENT)
    response.delete_cookie(COOKIE_NAME, path="/", httponly=True)
    return response
