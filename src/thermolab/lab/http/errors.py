"""HTTP answers of errors: each error class carries its status and a stable code.

Every 4xx body is ``{"detail": "...", "code": "...", "message": "..."}``:
``detail`` says what was wrong and what is allowed (the library's own message,
in English), ``code`` is a stable machine-readable name (``not_found``,
``conflict``...), ``message`` the code's sentence in the reader's language
(``thermolab.lab.error_messages``: the ``thermolab_lang`` cookie, else
``Accept-Language``; the answer's ``Content-Language`` names it). Request
validation failures are 422 with ``code = "invalid_request"`` and the
pydantic ``errors`` list. Unknown paths under ``/api`` answer 401 before
404/405, so they reveal nothing to a stranger.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import anyio.to_thread
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from thermolab.errors import (
    AccessDeniedError,
    ConflictError,
    NotFoundError,
    RigError,
    ThermoLabError,
    TurnEndedError,
    TurnExtensionRefusedError,
)
from thermolab.lab.camera import CameraError
from thermolab.lab.error_messages import LANGUAGE_COOKIE, error_message, negotiate_language
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.security import AuthenticationError, RateLimitedError
from thermolab.lab.service import Lab

__all__ = [
    "HttpFault",
    "all_error_codes",
    "error_response",
    "fault_of",
    "install_error_handlers",
    "request_language",
]


@dataclass(frozen=True, slots=True)
class HttpFault:
    """How an error class is answered: HTTP status and stable code."""

    status: int
    code: str


# The most specific class in an error's MRO decides (CameraError before RigError).
_FAULTS: dict[type[BaseException], HttpFault] = {
    AuthenticationError: HttpFault(401, "not_authenticated"),
    AccessDeniedError: HttpFault(403, "access_denied"),
    NotFoundError: HttpFault(404, "not_found"),
    ConflictError: HttpFault(409, "conflict"),
    TurnEndedError: HttpFault(409, "turn_ended"),
    TurnExtensionRefusedError: HttpFault(409, "extend_refused"),
    RigError: HttpFault(409, "rig_unavailable"),
    CameraError: HttpFault(503, "camera_unavailable"),
    RateLimitedError: HttpFault(429, "rate_limited"),
    ValueError: HttpFault(422, "invalid_parameter"),
}
_OTHER = HttpFault(400, "bad_request")
_HTTP_CODES = {404: "not_found", 405: "method_not_allowed", 413: "body_too_large"}


def fault_of(exc: BaseException) -> HttpFault:
    """Return how ``exc`` is answered (400 ``bad_request`` for an unlisted error).

    Examples
    --------
    >>> from thermolab.errors import InvalidParameterError
    >>> fault_of(InvalidParameterError("dt must be positive"))
    HttpFault(status=422, code='invalid_parameter')
    >>> fault_of(CameraError("no picture"))
    HttpFault(status=503, code='camera_unavailable')
    """
    for cls in type(exc).__mro__:
        fault = _FAULTS.get(cls)
        if fault is not None:
            return fault
    return _OTHER


def error_response(
    status: int,
    detail: str,
    code: str,
    headers: dict[str, str] | None = None,
    *,
    language: str = "en",
    extra: dict[str, Any] | None = None,
) -> JSONResponse:
    """The JSON answer of an error, with the code's sentence in ``language``."""
    message = error_message(code, language)
    body = {"detail": detail, "code": code, "message": message, **(extra or {})}
    return JSONResponse(
        body, status_code=status, headers={**(headers or {}), "Content-Language": language}
    )


def request_language(headers: Any, cookies: Any) -> str:
    """The language an answer to this request speaks (cookie first, then Accept-Language)."""
    return negotiate_language(headers.get("accept-language"), cookies.get(LANGUAGE_COOKIE))


def all_error_codes() -> frozenset[str]:
    """Every stable ``code`` an error answer can carry (each has a sentence in every language)."""
    return frozenset(
        {fault.code for fault in _FAULTS.values()}
        | {_OTHER.code, "http_error", "invalid_request", "cross_origin"}
        | set(_HTTP_CODES.values())
    )


def install_error_handlers(app: FastAPI) -> None:
    """Answer the library's errors, validation failures and HTTP errors as documented."""

    async def lab_error(request: Request, exc: Exception) -> JSONResponse:
        fault = fault_of(exc)
        headers: dict[str, str] = {}
        if isinstance(exc, AuthenticationError):
            headers["WWW-Authenticate"] = 'Cookie realm="ThermoLab"'
        if isinstance(exc, RateLimitedError):
            headers["Retry-After"] = str(max(1, math.ceil(exc.retry_after)))
        language = request_language(request.headers, request.cookies)
        return error_response(fault.status, str(exc), fault.code, headers, language=language)

    async def validation_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestValidationError)
        errors = [_plain_error(e) for e in exc.errors()]
        detail = "; ".join(_describe_error(e) for e in exc.errors()) or "invalid request"
        language = request_language(request.headers, request.cookies)
        return error_response(
            422, detail, "invalid_request", language=language, extra={"errors": errors}
        )

    async def http_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, StarletteHTTPException)
        path = request.url.path
        if exc.status_code in (404, 405) and path.startswith("/api/"):
            # Unknown paths under /api are private too: 401 first, then 404/405.
            lab: Lab = request.app.state.lab
            token = request.cookies.get(COOKIE_NAME)
            who = await anyio.to_thread.run_sync(lab.sessions.resolve, token)
            if who is None:
                return await lab_error(request, AuthenticationError("not logged in"))
        detail = exc.detail
        if exc.status_code == 404 and detail == "Not Found":
            detail = f"nothing at {request.method} {path}; see /openapi.json"
        elif exc.status_code == 405 and detail == "Method Not Allowed":
            allowed = (exc.headers or {}).get("Allow", "")
            detail = f"{request.method} is not allowed on {path}; use {allowed}"
        code = _HTTP_CODES.get(exc.status_code, "http_error")
        language = request_language(request.headers, request.cookies)
        return error_response(
            exc.status_code, str(detail), code, dict(exc.headers or {}), language=language
        )

    app.add_exception_handler(ThermoLabError, lab_error)
    app.add_exception_handler(RequestValidationError, validation_error)
    app.add_exception_handler(StarletteHTTPException, http_error)


# Fields whose submitted value is never repeated in an answer (ASVS V7.1.1, V8.3.x).
_SECRET_FIELDS = frozenset({"password", "currentPassword", "current_password"})


def _where(loc: tuple[Any, ...] | list[Any]) -> str:
    parts = [str(p) for p in loc]
    if parts and parts[0] in ("body", "path", "query", "header", "cookie"):
        kind, rest = parts[0], parts[1:]
        return ".".join(rest) if rest else f"request {kind}"
    return ".".join(parts) or "request"


def _describe_error(error: Any) -> str:
    kind = error.get("type", "")
    where = _where(error.get("loc", ()))
    if kind == "json_invalid":
        reason = (error.get("ctx") or {}).get("error", "not JSON")
        return f"the request body is not valid JSON ({reason})"
    if kind == "missing" and where == "request body":
        return "the request body is missing; send a JSON object"
    if kind == "extra_forbidden":
        return f"{where}: unknown field"
    message = error.get("msg", "invalid value")
    loc = error.get("loc", ())
    secret = bool(loc) and str(loc[-1]) in _SECRET_FIELDS
    if "input" in error and kind != "missing" and not secret:
        shown = repr(error["input"])
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        return f"{where}: {message} (got {shown})"
    return f"{where}: {message}"


def _plain_error(error: Any) -> dict[str, Any]:
    return {
        "loc": [str(p) for p in error.get("loc", ())],
        "type": str(error.get("type", "")),
        "msg": str(error.get("msg", "")),
    }
