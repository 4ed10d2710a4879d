"""Request size: bodies over the configured limit are refused with 413, unread.

A route that takes a file (a guide's picture) may have a larger allowance of
its own (:class:`BodyAllowance`), refused with its own code.
"""

from __future__ import annotations

import re
from collections.abc import Awaitable, Callable, Mapping, MutableMapping, Sequence
from dataclasses import dataclass
from typing import Any

from fastapi import HTTPException
from starlette.requests import HTTPConnection
from starlette.responses import Response

from thermolab.lab.http.errors import error_response, request_language

__all__ = [
    "ASGIApp",
    "BodyAllowance",
    "BodyLimit",
    "Message",
    "Receive",
    "Scope",
    "Send",
    "TooLargePage",
]

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]
# A path's own answer to a body over the limit: (connection, bytes seen, limit) -> response.
TooLargePage = Callable[[HTTPConnection, int, int], Response]


class _BodyTooLargeError(HTTPException):
    """Raised from inside the app while it reads the body; rendered by the error handler."""

    def __init__(self, received: int, limit: int, code: str) -> None:
        super().__init__(
            413, f"request body too large: over {limit} bytes (at least {received} sent)"
        )
        self.code = code  # the answer's code (the error handler reads it)


@dataclass(frozen=True, slots=True)
class BodyAllowance:
    """A larger body limit for one route: ``method`` on paths matching ``path``.

    A body over ``max_bytes`` is refused with 413 and ``code`` (the route's own
    refusal of a too large upload, so the answer is the same however large).
    """

    method: str
    path: re.Pattern[str]
    max_bytes: int
    code: str


class BodyLimit:
    """Refuse request bodies over ``max_bytes`` with 413, without reading them in full.

    ``allowances`` give some routes a limit of their own; ``pages`` answer the
    refusal on some paths with a page of their own instead of the JSON error
    (an LTI launch's, which a browser shows inside the LMS).
    """

    def __init__(
        self,
        app: ASGIApp,
        max_bytes: int,
        allowances: Sequence[BodyAllowance] = (),
        pages: Mapping[str, TooLargePage] | None = None,
    ) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.allowances = tuple(allowances)
        self.pages = dict(pages or {})

    def _limit(self, scope: Scope) -> tuple[int, str]:
        method, path = str(scope.get("method", "")).upper(), str(scope.get("path", ""))
        for allowance in self.allowances:
            if allowance.method == method and allowance.path.fullmatch(path):
                return allowance.max_bytes, allowance.code
        return self.max_bytes, "body_too_large"

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit, code = self._limit(scope)
        declared = _content_length(scope)
        if declared is not None and declared > limit:
            await self._refuse(scope, send, declared, limit, code)
            return
        received = 0
        started = False

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise _BodyTooLargeError(received, limit, code)
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
                await self._refuse(scope, send, received, limit, code)

    async def _refuse(self, scope: Scope, send: Send, size: int, limit: int, code: str) -> None:
        connection = HTTPConnection(scope)
        page = self.pages.get(str(scope.get("path", "")))
        response = (
            page(connection, size, limit)
            if page is not None
            else error_response(
                413,
                f"request body too large: {size} bytes, at most {limit} are accepted",
                code,
                language=request_language(connection.headers, connection.cookies),
            )
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
