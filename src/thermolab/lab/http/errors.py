"""HTTP answers of errors: each error class carries its status and a stable code.

Every 4xx body is ``{"detail": "...", "code": "...", "message": "..."}``:
``detail`` says what was wrong and what is allowed (the library's own message,
in English), ``code`` is a stable machine-readable name (``not_found``,
``conflict``...), ``message`` the code's sentence in the reader's language
(``thermolab.lab.error_messages``: the ``thermolab_lang`` cookie, else
``Accept-Language``; the answer's ``Content-Language`` names it). Every 422
adds ``errors``, one per problem: request validation failures (body, path,
query, and a body that is not UTF-8) with ``code = "invalid_request"``, the
lab's own refusals with ``"invalid_parameter"``; the OpenAPI publishes that
one shape (``ValidationErrorOut``) for every 422 instead of FastAPI's own.
Unknown paths under ``/api`` answer 401 before 404/405, so they reveal nothing
to a stranger; a wrong method gets 405 with ``Allow`` listing the methods the
path really has.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import anyio.to_thread
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError, WebSocketRequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.websockets import WebSocket

from thermolab.errors import (
    CONFLICT_CASES,
    AccessDeniedError,
    BookingClashError,
    BookingQuotaError,
    BookingSeriesClashError,
    ChannelInLoopError,
    ChannelNotOnRigError,
    ClassListError,
    ConflictError,
    CourseClosedError,
    CourseNameTakenError,
    FaultNotClearedError,
    GainRangeError,
    HostOfflineError,
    LabStartingError,
    LoopPairNotOnRigError,
    ModelPairError,
    NameTakenError,
    NobodyControlsError,
    NoOutputUnitError,
    NoRunError,
    NotClosedLoopError,
    NotControllerError,
    NotFoundError,
    PairChannelUnknownError,
    PairRoleError,
    PasswordChangeRequiredError,
    PasswordRejectedError,
    PreviousRunEndingError,
    RigBookedError,
    RigError,
    RigOutOfServiceError,
    RunInProgressError,
    SetpointNoStepError,
    SetpointRangeError,
    SettingNotForRigError,
    SettingRangeError,
    SettingsChangedError,
    SlotReversedError,
    SlotTooLongError,
    SlotZoneError,
    SpeedupRefusedError,
    ThermoLabError,
    TimeZoneError,
    TurnEndedError,
    TurnExtensionRefusedError,
    WrongEnrolCodeError,
)
from thermolab.lab.accounts.security import AuthenticationError, RateLimitedError
from thermolab.lab.error_messages import (
    LANGUAGE_COOKIE,
    error_message,
    negotiate_language,
    translate,
)
from thermolab.lab.guides.images import (
    ImageInvalidError,
    ImagePixelsError,
    ImageTooLargeError,
    ImageTypeError,
)
from thermolab.lab.http.credentials import resolve_principal
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.http.error_schemas import ValidationErrorOut
from thermolab.lab.live.fanout import CLOSE_BAD_REQUEST, CLOSE_UNAUTHORIZED, MAX_SEQ
from thermolab.lab.lti.errors import (
    LtiClaimError,
    LtiError,
    LtiFormTooLargeError,
    LtiJwksUnreachableError,
    LtiReplayError,
    LtiServiceError,
    LtiStateError,
    LtiTargetError,
    LtiThrottledError,
    LtiUnknownDeploymentError,
    LtiUnknownPlatformError,
)
from thermolab.lab.rigs.camera import CameraError
from thermolab.lab.service import Lab

__all__ = [
    "HttpFault",
    "all_error_codes",
    "api_methods",
    "error_response",
    "fault_of",
    "install_error_handlers",
    "invalid_response",
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
    NameTakenError: HttpFault(409, "name_taken"),
    CourseNameTakenError: HttpFault(409, "course_name_taken"),
    TurnEndedError: HttpFault(409, "turn_ended"),
    RunInProgressError: HttpFault(409, "run_in_progress"),
    PreviousRunEndingError: HttpFault(409, "previous_run_ending"),
    TurnExtensionRefusedError: HttpFault(409, "extend_refused"),
    RigError: HttpFault(409, "rig_unavailable"),
    CameraError: HttpFault(503, "camera_unavailable"),
    RateLimitedError: HttpFault(429, "rate_limited"),
    ValueError: HttpFault(422, "invalid_parameter"),
    # The closed loop's (issue #11).
    GainRangeError: HttpFault(422, "gain_out_of_range"),
    SetpointRangeError: HttpFault(422, "setpoint_out_of_range"),
    SetpointNoStepError: HttpFault(422, "setpoint_no_step"),
    NoOutputUnitError: HttpFault(422, "no_output_unit"),
    NoRunError: HttpFault(409, "no_run"),
    # Why a rig takes no turn now, and a controller's action by someone else (issue #24).
    RigOutOfServiceError: HttpFault(409, "rig_out_of_service"),
    FaultNotClearedError: HttpFault(409, "rig_fault_not_cleared"),
    LabStartingError: HttpFault(409, "lab_starting"),
    HostOfflineError: HttpFault(409, "host_offline"),
    NotControllerError: HttpFault(409, "not_controller"),
    NobodyControlsError: HttpFault(409, "nobody_controls"),
    NotClosedLoopError: HttpFault(409, "not_closed_loop"),
    # Courses and people (issue #10).
    ClassListError: HttpFault(422, "class_list_invalid"),
    WrongEnrolCodeError: HttpFault(403, "enrol_code_wrong"),
    CourseClosedError: HttpFault(409, "course_closed"),
    PasswordChangeRequiredError: HttpFault(403, "password_change_required"),
    # Teacher settings (issue #10).
    SettingRangeError: HttpFault(422, "setting_out_of_range"),
    SettingNotForRigError: HttpFault(422, "setting_not_for_rig"),
    SettingsChangedError: HttpFault(409, "settings_changed"),
    # A script's own speed-up of a twin for its turn (issue #22, item 5).
    SpeedupRefusedError: HttpFault(422, "speedup_refused"),
    # A rig's further channels (issue #22, item 1): a kit's heater 2 on a one-heater rig.
    ChannelNotOnRigError: HttpFault(422, "channel_not_on_rig"),
    # The closed loop's pair (issue #22, item 3): one the rig has; its heater is the PID's.
    LoopPairNotOnRigError: HttpFault(422, "loop_pair_not_on_rig"),
    ChannelInLoopError: HttpFault(409, "channel_in_loop"),
    # A run's input/output pair (issue #22): a channel the rig lacks, or one in the wrong role.
    PairChannelUnknownError: HttpFault(422, "pair_channel_unknown"),
    PairRoleError: HttpFault(422, "pair_wrong_role"),
    # A tuning table for a loop of another pair than its model's (a Q2 -> T2 model, Q1/T1).
    ModelPairError: HttpFault(422, "model_pair_mismatch"),
    # Bookings (issue #10, item 5).
    BookingClashError: HttpFault(409, "booking_clash"),
    RigBookedError: HttpFault(409, "rig_booked"),
    # Slot times and the booking tools (issue #24, item 7).
    SlotReversedError: HttpFault(422, "slot_ends_before_start"),
    SlotTooLongError: HttpFault(422, "slot_too_long"),
    SlotZoneError: HttpFault(422, "slot_zone_missing"),
    TimeZoneError: HttpFault(422, "time_zone_unknown"),
    BookingQuotaError: HttpFault(409, "booking_quota_exceeded"),
    BookingSeriesClashError: HttpFault(409, "booking_series_clash"),
    # The LTI 1.3 tool (issue #12): a refused launch, or a platform that failed us.
    LtiError: HttpFault(400, "lti_invalid_token"),
    LtiReplayError: HttpFault(400, "lti_replayed"),
    LtiClaimError: HttpFault(400, "lti_claim_invalid"),
    LtiTargetError: HttpFault(400, "lti_target_invalid"),
    LtiFormTooLargeError: HttpFault(413, "lti_form_too_large"),
    LtiThrottledError: HttpFault(429, "rate_limited"),
    LtiStateError: HttpFault(400, "lti_state_invalid"),
    LtiUnknownPlatformError: HttpFault(400, "lti_unknown_platform"),
    LtiUnknownDeploymentError: HttpFault(400, "lti_unknown_deployment"),
    LtiJwksUnreachableError: HttpFault(502, "lti_jwks_unreachable"),
    LtiServiceError: HttpFault(502, "lti_service_failed"),
    # Pictures of the guide pages (issue #10, item 1).
    ImageInvalidError: HttpFault(422, "image_invalid"),
    ImageTypeError: HttpFault(415, "image_type_unsupported"),
    ImageTooLargeError: HttpFault(413, "image_too_large"),
    ImagePixelsError: HttpFault(422, "image_too_many_pixels"),
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
            # A conflict that names its precise case answers with that code.
            case = getattr(exc, "case", None)
            return HttpFault(fault.status, case) if isinstance(case, str) else fault
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
        | {"lti_cookies_blocked", "lti_returning"}  # the LTI pages' sentences
        | {"database_unavailable"}  # http/outage.py's
        | set(CONFLICT_CASES)  # a ConflictError's precise cases
        | set(_HTTP_CODES.values())
    )


def install_error_handlers(app: FastAPI) -> None:
    """Answer the library's errors, validation failures and HTTP errors as documented."""

    async def lab_error(request: Request, exc: Exception) -> JSONResponse:
        fault = fault_of(exc)
        headers: dict[str, str] = {}
        if isinstance(exc, AuthenticationError):
            bearer = request.headers.get("authorization") is not None
            headers["WWW-Authenticate"] = f'{"Bearer" if bearer else "Cookie"} realm="ThermoLab"'
        if isinstance(exc, RateLimitedError):
            headers["Retry-After"] = str(max(1, math.ceil(exc.retry_after)))
        language = request_language(request.headers, request.cookies)
        if isinstance(exc, ClassListError):
            # One problem per bad line of the file, so a page can list them: its stable
            # code and values (the browser's catalogue words them), its sentence in the
            # reader's language, and the English one.
            def say(sentence: str) -> str:
                return translate(sentence, language)

            problems = [
                {
                    "loc": ["file", str(p.line)],
                    "type": p.code,
                    "msg": p.reason,
                    "params": dict(p.params),
                    "message": p.sentence(say),
                }
                for p in exc.problems
            ]
            return invalid_response(str(exc), fault.code, problems, language=language)
        if isinstance(exc, PasswordRejectedError):
            # Why the password is refused, in the reader's language: the page shows it.
            refusal = {"loc": ["body", "password"], "type": exc.problem, "msg": str(exc)}
            message = exc.describe(lambda text: translate(text, language))
            return invalid_response(
                str(exc), fault.code, [refusal], language=language, message=message
            )
        if fault.status == 422:
            # A setting's refusal names the value it is about, as a schema error would.
            about = exc if isinstance(exc, SettingRangeError | SettingNotForRigError) else None
            where = [] if about is None else ["body", "values", about.setting]
            problem = {"loc": where, "type": fault.code, "msg": str(exc)}
            return invalid_response(str(exc), fault.code, [problem], language=language)
        # A booking refusal names the slot in the way, for the page to show.
        extra: dict[str, Any] | None = None
        if isinstance(exc, BookingClashError | RigBookedError):
            extra = {"slot": exc.slot}
        elif isinstance(exc, BookingQuotaError):
            extra = {"quota": exc.quota}
        elif isinstance(exc, BookingSeriesClashError):
            extra = {"clashes": exc.clashes}
        return error_response(
            fault.status, str(exc), fault.code, headers, language=language, extra=extra
        )

    async def validation_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestValidationError)
        errors = [_plain_error(e) for e in exc.errors()]
        detail = "; ".join(_describe_error(e) for e in exc.errors()) or "invalid request"
        language = request_language(request.headers, request.cookies)
        return invalid_response(detail, "invalid_request", errors, language=language)

    async def http_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, StarletteHTTPException)
        path = request.url.path
        status, headers = exc.status_code, dict(exc.headers or {})
        if status == 400 and isinstance(exc.__cause__, ValueError):
            # FastAPI answers 400 for a JSON body it cannot decode as text (not UTF-8);
            # the API documents every unreadable body as a 422.
            detail = f"the request body is not valid JSON ({exc.__cause__})"
            problem = {"loc": ["body"], "type": "json_invalid", "msg": "not UTF-8 JSON"}
            return invalid_response(detail, "invalid_request", [problem])
        if status in (404, 405) and path.startswith("/api/"):
            # Unknown paths under /api are private too: 401 first, then 404/405.
            lab: Lab = request.app.state.lab
            cookie = request.cookies.get(COOKIE_NAME)
            authorization = request.headers.get("authorization")
            who = await anyio.to_thread.run_sync(
                lambda: resolve_principal(lab, cookie=cookie, authorization=authorization)
            )
            if who is None:
                return await lab_error(request, AuthenticationError("not logged in"))
            # Starlette names the methods of the first route that matched the path (or
            # the static files' GET, HEAD); the truth is every API route of the path.
            allowed = api_methods(request.app, path)
            status = 405 if allowed else 404
            headers.pop("Allow", None)
            if allowed:
                headers["Allow"] = ", ".join(allowed)
        detail = str(exc.detail)
        if status == 404 and exc.status_code in (404, 405):
            detail = f"nothing at {request.method} {path}; see /openapi.json"
        elif status == 405:
            detail = f"{request.method} is not allowed on {path}; use {headers.get('Allow', '')}"
        own = getattr(exc, "code", None)  # a body limit's own code (http/limits.py)
        code = own if isinstance(own, str) else _HTTP_CODES.get(status, "http_error")
        language = request_language(request.headers, request.cookies)
        return error_response(status, detail, code, headers, language=language)

    async def handshake_refused(websocket: WebSocket, exc: Exception) -> None:
        # FastAPI's default closes before accepting: an HTTP 403 that says nothing. The
        # live protocol's refusal is a close code (docs/live-protocol.md), and a
        # stranger learns nothing before logging in.
        lab: Lab = websocket.app.state.lab
        token = websocket.cookies.get(COOKIE_NAME)
        who = await anyio.to_thread.run_sync(lab.sessions.resolve, token)
        await websocket.accept()
        if who is None:
            await websocket.close(CLOSE_UNAUTHORIZED, "not logged in")
        else:
            await websocket.close(CLOSE_BAD_REQUEST, _HANDSHAKE_REFUSAL)

    app.add_exception_handler(ThermoLabError, lab_error)
    app.add_exception_handler(WebSocketRequestValidationError, handshake_refused)
    app.add_exception_handler(RequestValidationError, validation_error)
    app.add_exception_handler(StarletteHTTPException, http_error)
    _publish_one_validation_error(app)


def invalid_response(
    detail: str,
    code: str,
    errors: list[dict[str, Any]],
    *,
    language: str = "en",
    message: str | None = None,
) -> JSONResponse:
    """The JSON answer of a 422 (``ValidationErrorOut``); ``message`` replaces the code's
    sentence when the error has a more precise one in the reader's language."""
    extra: dict[str, Any] = {"errors": errors}
    if message is not None:
        extra["message"] = message
    return error_response(422, detail, code, language=language, extra=extra)


def api_methods(app: FastAPI, path: str) -> list[str]:
    """The HTTP methods the API answers on ``path``, sorted (empty: no such path).

    Read from the published OpenAPI, which lists every API route: the ``Allow``
    header and ``/openapi.json`` cannot disagree.
    """
    table: list[tuple[re.Pattern[str], list[str]]] | None = getattr(app.state, "api_methods", None)
    if table is None:
        table = [
            (re.compile(re.sub(r"\\\{[^}]+\\\}", "[^/]+", re.escape(template))), sorted(ops))
            for template, ops in app.openapi().get("paths", {}).items()
        ]
        app.state.api_methods = table
    methods = {m.upper() for pattern, ops in table if pattern.fullmatch(path) for m in ops}
    return sorted(methods)


def _publish_one_validation_error(app: FastAPI) -> None:
    """Make ``/openapi.json`` document every 422 as ``ValidationErrorOut``, the body sent.

    FastAPI adds its own ``HTTPValidationError`` (``detail`` a list) to every route
    with parameters that does not document a 422 itself; the lab never sends it.
    """
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:
            return app.openapi_schema
        schema = build()
        components = schema.setdefault("components", {}).setdefault("schemas", {})
        if "ValidationErrorOut" not in components:  # no route documents a 422 itself
            own = ValidationErrorOut.model_json_schema(ref_template=_REF, mode="serialization")
            components.update(own.pop("$defs", {}))
            components["ValidationErrorOut"] = own
        for operations in schema.get("paths", {}).values():
            for operation in operations.values():
                invalid = operation.get("responses", {}).get("422")
                if invalid is not None:
                    published = {"$ref": _REF.format(model="ValidationErrorOut")}
                    invalid["content"] = {"application/json": {"schema": published}}
        for unused in ("HTTPValidationError", "ValidationError"):
            components.pop(unused, None)
        app.openapi_schema = schema
        return schema

    app.openapi = openapi  # type: ignore[method-assign]


_REF = "#/components/schemas/{model}"
# The only query parameter of the live socket; a close reason holds at most 123 bytes.
_HANDSHAKE_REFUSAL = f"since must be a whole number from 0 to {MAX_SEQ} (a seq this server sent)"


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
    # Only a field's own scalar value is repeated: a whole body (a form, bytes, an
    # object or a list) may carry a password in any field or encoding.
    scalar = isinstance(error.get("input"), int | float | str) and where != "request body"
    if "input" in error and kind != "missing" and not secret and scalar:
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
