"""A follower's requests about rigs and runs, answered by the owner (:mod:`~thermolab.lab.fleet`).

An ASGI middleware: on a follower, every HTTP request under ``/api/rigs``,
``/api/runs`` and ``/api/control`` is sent as it came (method, path, query,
headers, body) to the owner worker's address, and the owner's answer goes
back unchanged — its status, its ``code``, its headers. One process thus
decides every turn, queue place and run, whichever worker a browser reached.
The HTTP client is httpx (already the project's), with a connection pool
kept for the worker's life. When no owner was heard recently, the answer is
503 ``rig_unavailable``.

Rig hosts (``thermolab agent``) link to the owner only: a follower accepts
their WebSocket and closes it at once with
:data:`~thermolab.agent.protocol.CLOSE_NOT_OWNER` (:func:`refuse_agent_link`),
and the agent dials the next address it was given. The hosts page
(``/api/agents``, the owner's links) is forwarded like the rigs.
"""

from __future__ import annotations

from collections.abc import Callable

import httpx
from starlette.types import ASGIApp, Message, Receive, Scope, Send
from starlette.websockets import WebSocket

from thermolab.agent.protocol import CLOSE_NOT_OWNER
from thermolab.lab.http.errors import error_response

__all__ = ["FORWARDED_PREFIXES", "ForwardToOwner", "refuse_agent_link"]

FORWARDED_PREFIXES = ("/api/rigs", "/api/runs", "/api/control", "/api/agents")
"""Paths the owner answers (a follower forwards them)."""

# Connection-level headers stay with each hop; ``Host`` (and ``Origin``) go as they came,
# so that the owner's browser guard judges the request the browser made.

_HOP_BY_HOP = frozenset(
    {
        b"connection",
        b"keep-alive",
        b"transfer-encoding",
        b"upgrade",
        b"content-length",
        b"te",
        b"trailer",
        b"proxy-authorization",
        b"proxy-authenticate",
    }
)


async def refuse_agent_link(ws: WebSocket) -> None:
    """A follower's answer to a rig host: not here — dial the owner (the next address)."""
    await ws.accept()
    await ws.close(code=CLOSE_NOT_OWNER, reason="this worker does not own the rigs")


def _forwarded(path: str) -> bool:
    return any(path == p or path.startswith(p + "/") for p in FORWARDED_PREFIXES)


class ForwardToOwner:
    """Forward rig and run requests to the owner whose address ``owner_url()`` gives.

    Parameters
    ----------
    app : ASGIApp
    owner_url : callable
        The owner's base address now, or ``None`` when unknown.
    here : callable, optional
        ``True`` once this worker owns the rigs (a standby promoted): nothing
        is forwarded from then on.
    timeout : float
        Seconds the owner has to answer.
    """

    def __init__(
        self,
        app: ASGIApp,
        owner_url: Callable[[], str | None],
        here: Callable[[], bool] = lambda: False,
        timeout: float = 30.0,
    ) -> None:
        self.app = app
        self.owner_url = owner_url
        self.here = here
        self._client = httpx.AsyncClient(timeout=timeout)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or not _forwarded(scope["path"]) or self.here():
            await self.app(scope, receive, send)
            return
        owner = self.owner_url()
        if owner is None:
            response = error_response(
                503, "the worker that owns the rigs is not reachable now", "rig_unavailable"
            )
            await response(scope, receive, send)
            return
        body = bytearray()
        while True:
            message: Message = await receive()
            body += message.get("body", b"")
            if not message.get("more_body", False):
                break
        headers = [(k, v) for k, v in scope["headers"] if k.lower() not in _HOP_BY_HOP]
        query = scope.get("query_string", b"").decode("latin-1")
        url = (
            owner.rstrip("/") + scope["raw_path"].decode("latin-1") + (f"?{query}" if query else "")
        )
        try:
            request = self._client.build_request(
                scope["method"], url, headers=headers, content=bytes(body)
            )
            answer = await self._client.send(request, stream=True)
        except httpx.HTTPError:
            response = error_response(
                503, "the worker that owns the rigs did not answer", "rig_unavailable"
            )
            await response(scope, receive, send)
            return
        try:
            await send(
                {
                    "type": "http.response.start",
                    "status": answer.status_code,
                    "headers": [
                        (k, v) for k, v in answer.headers.raw if k.lower() not in _HOP_BY_HOP
                    ],
                }
            )
            async for chunk in answer.aiter_raw():
                await send({"type": "http.response.body", "body": chunk, "more_body": True})
            await send({"type": "http.response.body", "body": b"", "more_body": False})
        finally:
            await answer.aclose()
