"""What every route depends on: the lab, the logged-in user, path parameters, error docs.

Routes are plain functions: FastAPI runs them in its thread pool, and each
opens its own short database transactions.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import Depends, Path, Query, Request, Security
from fastapi.security import APIKeyCookie, HTTPAuthorizationCredentials, HTTPBearer

from thermolab.errors import AccessDeniedError, PasswordChangeRequiredError
from thermolab.lab.accounts.security import AuthenticationError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.audit.log import AuditAction
from thermolab.lab.config.model import RIG_ID
from thermolab.lab.http.credentials import resolve_principal
from thermolab.lab.http.error_schemas import ErrorOut, ValidationErrorOut
from thermolab.lab.service import Lab
from thermolab.lab.spreadsheets import SheetDialect, sheet_dialect

__all__ = [
    "AUTHENTICATED",
    "COOKIE_NAME",
    "USERNAME_PATTERN",
    "LabDep",
    "RigId",
    "RigQuery",
    "RunId",
    "SheetDep",
    "UserDep",
    "UserQuery",
    "Username",
    "audit",
    "client_address",
    "current_user",
    "documented_errors",
    "get_lab",
]

COOKIE_NAME = "thermolab_session"

_cookie = APIKeyCookie(
    name=COOKIE_NAME,
    auto_error=False,
    description="Session cookie set by POST /api/session.",
)
_bearer = HTTPBearer(
    auto_error=False,
    description="A personal API token (POST /api/tokens) for scripts, instead of the cookie.",
)
_READS = frozenset({"GET", "HEAD", "OPTIONS"})


def documented_errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    """The OpenAPI ``responses`` entry of a route that may answer ``codes``."""
    shown: dict[int | str, dict[str, Any]] = {}
    for code in codes:
        model = ValidationErrorOut if code == 422 else ErrorOut
        shown[code] = {"model": model}
    return shown


def get_lab(request: Request) -> Lab:
    """Return the :class:`~thermolab.lab.service.Lab` the app serves."""
    lab: Lab = request.app.state.lab
    return lab


LabDep = Annotated[Lab, Depends(get_lab)]


def current_user(
    request: Request,
    lab: LabDep,
    token: Annotated[str | None, Security(_cookie)],
    bearer: Annotated[HTTPAuthorizationCredentials | None, Security(_bearer)],
) -> Principal:
    """Return the user of the request: a login's cookie or an API token (``Bearer``).

    With an ``Authorization`` header only the token counts (see
    :mod:`~thermolab.lab.http.credentials`). A read-only token may only read.

    Raises
    ------
    AuthenticationError
        Without a live session or token (HTTP 401).
    AccessDeniedError
        A read-only token asking for a change (HTTP 403).
    """
    authorization = request.headers.get("authorization")
    if authorization is None and not token:
        raise AuthenticationError(
            "not logged in: POST /api/session with your user name and password, "
            "or send a personal API token as 'Authorization: Bearer <token>'"
        )
    principal = resolve_principal(lab, cookie=token, authorization=authorization)
    if principal is None:
        if authorization is not None:
            raise AuthenticationError(
                "this API token is unknown, revoked or expired (send 'Authorization: Bearer "
                "<token>' with a token from your page in the lab)"
            )
        raise AuthenticationError("your session has ended; log in again")
    if principal.read_only and request.method.upper() not in _READS:
        raise AccessDeniedError("this API token is read-only: it may only read (GET)")
    if principal.must_change_password and not _changes_password(request):
        raise PasswordChangeRequiredError(
            "your password is a temporary one: choose your own first "
            f"(PUT /api/users/{principal.username}/password)"
        )
    return principal


def _changes_password(request: Request) -> bool:
    """What a login with a temporary password may do: see who it is, log out, change it."""
    path = request.url.path
    if path == "/api/session":
        return True
    return (
        request.method.upper() == "PUT"
        and path.startswith("/api/users/")
        and path.endswith("/password")
    )


UserDep = Annotated[Principal, Depends(current_user)]


def client_address(request: Request) -> str:
    """The client's address as the server saw it (``unknown`` without one)."""
    return request.client.host if request.client is not None else "unknown"


def audit(
    lab: Lab,
    who: Principal,
    request: Request,
    action: AuditAction,
    target: str,
    **detail: Any,
) -> None:
    """Write ``who`` did ``action`` on ``target`` to the audit log (no secret in ``detail``)."""
    lab.audit.record(who.username, action, target, address=client_address(request), detail=detail)


# Every path and query parameter is bounded in the schema (tests/lab/test_contract.py
# walks /openapi.json): a rig id as the configuration allows it, a user name as
# normalize_username accepts it (in any case: names are case-insensitive).
USERNAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._@-]{0,63}$"
RigId = Annotated[
    str, Path(min_length=1, max_length=64, pattern=RIG_ID.pattern, description="the rig's id")
]
Username = Annotated[
    str,
    Path(min_length=1, max_length=64, pattern=USERNAME_PATTERN, description="a user name"),
]
RigQuery = Annotated[
    str | None,
    Query(min_length=1, max_length=64, pattern=RIG_ID.pattern, description="only this rig"),
]
UserQuery = Annotated[
    str | None,
    Query(
        min_length=1,
        max_length=64,
        pattern=USERNAME_PATTERN,
        description="only this user's runs (teachers: anyone; students: themselves only)",
    ),
]
# The largest row id the databases store (a signed 32-bit INTEGER on PostgreSQL): a
# larger id in a path is refused by the schema (422) instead of failing in the driver.
MAX_ROW_ID = 2**31 - 1

RunId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="the run's number")]

AUTHENTICATED: dict[str, Any] = {
    "dependencies": [Depends(current_user)],
    "responses": documented_errors(401),
}
"""Keyword arguments of an ``APIRouter`` whose every route needs a logged-in user."""


def spreadsheet_form(
    dialect: Annotated[
        Literal["pt-BR", "en", "es"] | None,
        Query(
            description="the spreadsheet form for this language (';' and decimal comma in pt-BR "
            "and es, a BOM, local times, words in the language); left out: the machine form"
        ),
    ] = None,
    tz: Annotated[
        str | None,
        Query(
            min_length=1,
            max_length=64,
            pattern=r"^[A-Za-z][A-Za-z0-9_+\-]*(/[A-Za-z0-9_+\-]+){0,2}$",
            description="the spreadsheet form's time zone (IANA, e.g. America/Sao_Paulo; UTC "
            "when left out)",
        ),
    ] = None,
) -> SheetDialect | None:
    """The CSV form a download asks for (``None``: the machine form)."""
    return sheet_dialect(dialect, tz)


#: A CSV route's ``?dialect=pt-BR&tz=America/Sao_Paulo`` (:mod:`thermolab.lab.spreadsheets`).
SheetDep = Annotated[SheetDialect | None, Depends(spreadsheet_form)]
