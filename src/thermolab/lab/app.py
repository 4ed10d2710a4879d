"""The lab's web application: :func:`create_app`.

The app serves the JSON API under ``/api`` (documented at ``/openapi.json``
and ``/docs``) and, when given a folder, the browser interface at ``/``. It
does not import :mod:`thermolab.web`: ``thermolab serve`` hands the folder in.

Every 4xx answer is JSON with a ``detail`` sentence naming the problem. The
lab's exceptions map to status codes as follows: not logged in or wrong
password 401, not allowed 403, unknown rig/user/path 404, clash with the
current state 409, bad value 422, too many logins 429 (with Retry-After);
a body over the configured size is refused with 413 before it is read in full.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections.abc import AsyncIterator, Awaitable, Callable, MutableMapping
from pathlib import Path
from typing import Any

import anyio.to_thread
from fastapi import FastAPI, HTTPException, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException

from thermolab import __version__
from thermolab.errors import (
    AccessDeniedError,
    ConflictError,
    NotFoundError,
    RigError,
    ThermoLabError,
)
from thermolab.lab.api import COOKIE_NAME, router
from thermolab.lab.camera import CameraError
from thermolab.lab.config import LabConfig
from thermolab.lab.hub import device_opener
from thermolab.lab.security import AuthenticationError, RateLimitedError
from thermolab.lab.service import Lab
from thermolab.lab.stream import LiveBroadcaster

__all__ = ["create_app"]

log = logging.getLogger(__name__)

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]


def create_app(
    config: LabConfig,
    static_dir: Path | None = None,
    *,
    lab: Lab | None = None,
    close_lab: bool | None = None,
    sweep_interval: float | None = 1.0,
) -> FastAPI:
    """Build the lab's ASGI application.

    Parameters
    ----------
    config : LabConfig
        The lab's configuration.
    static_dir : Path, optional
        Folder of the browser interface, served at ``/``.
    lab : Lab, optional
        A lab built by the caller (tests inject a clock, a cheap password
        hasher, rig drivers); by default one is built from ``config``, with the
        rigs opened by :func:`thermolab.rigs.open_rig`. The app starts it
        (migrations, safe state) when it starts.
    close_lab : bool, optional
        Close the lab when the app shuts down (runs aborted, rigs safe);
        default: only a lab the app built itself. ``thermolab serve`` passes
        ``True``: uvicorn re-raises SIGTERM after its shutdown, so nothing
        after ``uvicorn.run`` would run.
    sweep_interval : float or None
        Seconds between sweeps of the access limits in the background;
        ``None`` for none (tests sweep by hand).

    Returns
    -------
    FastAPI

    Examples
    --------
    >>> import tempfile
    >>> from thermolab.lab.config import default_config
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     app = create_app(default_config(Path(tmp)))
    >>> "/api/rigs/{rig_id}/control" in app.openapi()["paths"]
    True
    """
    owned = lab is None if close_lab is None else close_lab
    the_lab = lab if lab is not None else Lab(config, opener=device_opener(config.speedup))
    live = LiveBroadcaster(the_lab)
    the_lab.add_listener(live)

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        report = await anyio.to_thread.run_sync(the_lab.start)
        app.state.startup = report
        live.bind(asyncio.get_running_loop())
        sweeper = (
            asyncio.create_task(_sweep_forever(the_lab, sweep_interval))
            if sweep_interval is not None
            else None
        )
        try:
            yield
        finally:
            live.bind(None)
            if sweeper is not None:
                sweeper.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await sweeper
            if owned:
                await anyio.to_thread.run_sync(the_lab.close)

    app = FastAPI(
        title=config.title,
        version=__version__,
        description=(
            "ThermoLab remote laboratory: watch rigs, take turns controlling them, "
            "identify the model of a temperature control system. Log in with "
            "POST /api/session; every other route needs the session cookie."
        ),
        lifespan=lifespan,
    )
    app.state.lab = the_lab
    app.state.live = live
    app.include_router(router)
    app.add_api_websocket_route("/api/rigs/{rig_id}/live", live.endpoint, name="live")
    _install_error_handlers(app)
    if static_dir is not None:
        app.mount("/", StaticFiles(directory=static_dir, html=True), name="web")
    app.add_middleware(_BodyLimit, max_bytes=config.access.max_body_bytes)
    app.add_middleware(_LoginsWatch, on_change=live.sessions_changed)
    return app


async def _sweep_forever(lab: Lab, interval: float) -> None:
    while True:
        await asyncio.sleep(interval)
        try:
            await anyio.to_thread.run_sync(lab.sweep)
        except Exception:  # a failed sweep must not stop the next ones
            log.exception("sweep of the access limits failed")


# -- errors -------------------------------------------------------------------------------------


def _error(status: int, detail: str, headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse({"detail": detail}, status_code=status, headers=headers)


def _status_of(exc: ThermoLabError) -> int:
    if isinstance(exc, AuthenticationError):
        return 401
    if isinstance(exc, AccessDeniedError):
        return 403
    if isinstance(exc, NotFoundError):
        return 404
    if isinstance(exc, CameraError):
        return 503
    if isinstance(exc, ConflictError | RigError):
        return 409
    if isinstance(exc, RateLimitedError):
        return 429
    if isinstance(exc, ValueError):
        return 422
    return 400


def _install_error_handlers(app: FastAPI) -> None:
    async def lab_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, ThermoLabError)
        status = _status_of(exc)
        headers: dict[str, str] = {}
        if isinstance(exc, AuthenticationError):
            headers["WWW-Authenticate"] = 'Cookie realm="ThermoLab"'
        if isinstance(exc, RateLimitedError):
            headers["Retry-After"] = str(max(1, math.ceil(exc.retry_after)))
        return _error(status, str(exc), headers)

    async def validation_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestValidationError)
        errors = [_plain_error(e) for e in exc.errors()]
        detail = "; ".join(_describe_error(e) for e in exc.errors()) or "invalid request"
        return JSONResponse({"detail": detail, "errors": errors}, status_code=422)

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
        return _error(exc.status_code, str(detail), dict(exc.headers or {}))

    app.add_exception_handler(ThermoLabError, lab_error)
    app.add_exception_handler(RequestValidationError, validation_error)
    app.add_exception_handler(StarletteHTTPException, http_error)


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
    if "input" in error and kind != "missing":
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


# -- logins ending ------------------------------------------------------------------------------


class _LoginsWatch:
    """Call ``on_change`` after a request that may have ended logins succeeds.

    Logging out or in again (``/api/session``), changing a password or removing
    an account (``/api/users/...``): the live stream then closes the sockets
    of the logins that are gone.
    """

    def __init__(self, app: ASGIApp, on_change: Callable[[], None]) -> None:
        self.app = app
        self.on_change = on_change

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        path = scope.get("path", "")
        if (
            scope["type"] != "http"
            or scope.get("method") in ("GET", "HEAD", "OPTIONS")
            or not (path == "/api/session" or path.startswith("/api/users/"))
        ):
            await self.app(scope, receive, send)
            return
        status = 500

        async def watching_send(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            await send(message)

        await self.app(scope, receive, watching_send)
        if status < 400:
            self.on_change()


# -- request size ------------------------------------------------------------------------------


class _BodyTooLargeError(HTTPException):
    """Raised from inside the app while it reads the body; rendered by the error handler."""

    def __init__(self, received: int, limit: int) -> None:
        super().__init__(
            413, f"request body too large: over {limit} bytes (at least {received} sent)"
        )


class _BodyLimit:
    """Refuse request bodies over ``max_bytes`` with 413, without reading them in full."""

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = _content_length(scope)
        if declared is not None and declared > self.max_bytes:
            await self._refuse(send, declared)
            return
        received = 0
        started = False

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise _BodyTooLargeError(received, self.max_bytes)
            return message

        async def tracking_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracking_send)
        except _BodyTooLargeError:
            if not started:
                await self._refuse(send, received)

    async def _refuse(self, send: Send, size: int) -> None:
        response = _error(
            413, f"request body too large: {size} bytes, at most {self.max_bytes} are accepted"
        )
        await send(
            {
                "type": "http.response.start",
                "status": 413,
                "headers": response.raw_headers,
            }
        )
        await send({"type": "http.response.body", "body": response.body})


def _content_length(scope: Scope) -> int | None:
    for name, value in scope.get("headers", []):
        if name == b"content-length":
            try:
                return int(value)
            except ValueError:
                return None
    return None
