"""A follower's requests about rigs and runs, answered by the owner.

Who owns the rigs and who follows is :mod:`~thermolab.lab.fleet.workers`' business.

An ASGI middleware: on a follower, every HTTP request under ``/api/rigs``,
``/api/runs`` and ``/api/control`` is sent as it came (method, path, query,
headers, body) to the owner worker's address, and the owner's answer goes
back unchanged — its status, its ``code``, its headers. One process thus
decides every turn, queue place and run, whichever worker a browser reached.
The HTTP client is httpx (already the project's), with a connection pool
kept for the worker's life.

While no owner answers — none heard recently, or the one heard refuses the
connection (killed: a standby is taking over) — a request waits for an owner
(:data:`~thermolab.lab.fleet.workers.OWNER_WAIT`, a takeover's longest gap) instead
of failing: it is woken by each owner announcement
(:meth:`~thermolab.lab.fleet.workers.Fleet.on_owner`)
and sent to the owner then; a worker promoted meanwhile answers it itself.
Sending it again is safe, even a POST: a refused connection carried no
request. Only after the wait is the answer 503 ``rig_unavailable`` (with
``Retry-After``). A request whose client hangs up while it waits (a
script's timeout) is dropped, never applied behind the client's back. A
request that was sent and got no answer (the owner died reading it, or timed
out) is not sent again — the owner may have applied it — and is answered 503
at once.

An owner served over HTTPS (``--advertise https://...``) is checked against
the system's CAs and the lab's own (``thermolab serve --ca``, the file its rig
hosts' ``--ca`` names: :func:`owner_tls`), so a fleet on a private CA works.
A try that cannot reach the owner is logged (once while the reason stays the
same): a certificate the follower does not trust is thus named in its log, not
only felt as held requests.

Rig hosts (``thermolab agent``) link to the owner only: a follower accepts
their WebSocket and closes it with
:data:`~thermolab.agent.protocol.CLOSE_NOT_OWNER` (:func:`refuse_agent_link`),
and the agent dials the next address it was given. A **standby** first
waits for the next announcement of an owner (a live one announces every
second): if none comes, the owner is dead and a takeover is under way, so the
host is held — not refused, which would send it round its list while its
grace runs out — until the takeover is decided: this worker owns (it serves
the link, :func:`hold_agent_link` returns ``True``), or another owner is
heard (the host is refused and dials on), or
:data:`~thermolab.agent.protocol.HELLO_HOLD` passes. The hosts page
(``/api/agents``, the owner's links) is forwarded like the rigs.
"""

from __future__ import annotations

import asyncio
import logging
import math
import ssl
import time
from asyncio import FIRST_COMPLETED
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send
from starlette.websockets import WebSocket, WebSocketDisconnect

from thermolab.agent.protocol import CLOSE_NOT_OWNER, HELLO_HOLD
from thermolab.lab.fleet.workers import ANNOUNCE_INTERVAL, OWNER_WAIT
from thermolab.lab.http.errors import error_response

if TYPE_CHECKING:
    import httpx

__all__ = [
    "FORWARDED_PREFIXES",
    "ForwardToOwner",
    "hold_agent_link",
    "owner_tls",
    "refuse_agent_link",
]

log = logging.getLogger(__name__)

_HOLD_LOOK = 0.05
"""Seconds between a held host's looks at who owns the rigs."""

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


def owner_tls(cafile: str | None = None) -> ssl.SSLContext:
    """How a follower checks the owner's certificate: the system's CAs, and ``cafile``'s.

    Raises
    ------
    OSError, ssl.SSLError
        ``cafile`` cannot be read or holds no certificate.
    """
    context = ssl.create_default_context()
    if cafile is not None:
        context.load_verify_locations(cafile=cafile)
    return context


async def refuse_agent_link(ws: WebSocket, *, accepted: bool = False) -> None:
    """A follower's answer to a rig host: not here — dial the owner (the next address)."""
    if not accepted:
        await ws.accept()
    await ws.close(code=CLOSE_NOT_OWNER, reason="this worker does not own the rigs")


async def hold_agent_link(
    ws: WebSocket,
    *,
    owns: Callable[[], bool],
    announcements: Callable[[], int],
    wait: float = min(OWNER_WAIT, HELLO_HOLD),
) -> str | None:
    """A standby's answer to a rig host: held while no owner is heard, refused once one is.

    Returns the host's first message (its ``Hello``, read: the WebSocket
    accepted) when this worker took the rigs over meanwhile: the caller serves
    the link with it. ``None``: the host was refused. ``announcements()`` counts
    the owner announcements heard; ``owns()`` says whether this worker owns the
    rigs now.

    The Hello is read before the hold: the server reads nothing more from a
    connection whose message the application has not taken (uvicorn pauses
    reading), so a held host's pings went unanswered and it dropped the link
    after its ping timeout (2-3 s), long before a takeover's 17 s.
    """
    await ws.accept()
    heard = announcements()
    deadline = time.monotonic() + wait
    try:
        hello = await asyncio.wait_for(ws.receive_text(), wait)
    except (TimeoutError, WebSocketDisconnect, KeyError):  # KeyError: a bytes message
        await refuse_agent_link(ws, accepted=True)
        return None
    while time.monotonic() < deadline:
        if owns():
            log.info("a rig host held through the takeover is served here")
            return hello
        if announcements() != heard:
            break  # an owner is alive (or was just decided elsewhere): the host dials it
        await asyncio.sleep(_HOLD_LOOK)
    await refuse_agent_link(ws, accepted=True)
    return None


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
    wait : float
        Seconds a request waits for an owner that answers before 503.
    on_owner : callable, optional
        Registers a listener to call, from any thread, each time an owner is
        heard (:meth:`~thermolab.lab.fleet.workers.Fleet.on_owner`): a waiting request
        is sent at once then. Without it, waiting requests try again every
        announcement interval.
    tls : ssl.SSLContext, optional
        Checks an ``https://`` owner's certificate (default :func:`owner_tls`:
        the system's CAs).

    Notes
    -----
    Waiting requests are not counted here: each is one coroutine and its
    body, and the server's connection limit (``--max-connections``) bounds
    how many there are.
    """

    def __init__(
        self,
        app: ASGIApp,
        owner_url: Callable[[], str | None],
        here: Callable[[], bool] = lambda: False,
        timeout: float = 30.0,
        wait: float = OWNER_WAIT,
        on_owner: Callable[[Callable[[], None]], None] | None = None,
        tls: ssl.SSLContext | None = None,
    ) -> None:
        self.app = app
        self.owner_url = owner_url
        self.here = here
        self.wait = wait
        # A try's connection gets one announcement interval: a dead owner's machine may drop
        # the connection attempt unanswered, and the next owner's address, announced meanwhile,
        # is then tried within about one more interval.
        # Imported here, by a fleet's follower only (see lti/services.py: httpx brings its
        # command line's libraries, 0.2-0.3 s of a server's start).
        import httpx

        self._client = httpx.AsyncClient(
            timeout=httpx.Timeout(timeout, connect=min(timeout, ANNOUNCE_INTERVAL)),
            verify=tls if tls is not None else owner_tls(),
        )
        self._unreachable = ""  # why the owner could not be reached, as last logged
        self._loop: asyncio.AbstractEventLoop | None = None
        self._owner_heard = asyncio.Event()
        if on_owner is not None:
            on_owner(self._heard_owner)

    def _heard_owner(self) -> None:
        # Any thread (the bus's): wake the waiting requests in the server's loop.
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._wake)

    def _wake(self) -> None:
        # Each waiter holds the event of its wait: set it, and later waits get a fresh one.
        heard, self._owner_heard = self._owner_heard, asyncio.Event()
        heard.set()

    def _closing_on_shutdown(self, receive: Receive) -> Receive:
        # The server stopping: the pool's connections to the owner close with it.
        async def received() -> Message:
            message = await receive()
            if message["type"] == "lifespan.shutdown":
                await self._client.aclose()
            return message

        return received

    async def _news_of_owner(self, timeout: float, hung_up: asyncio.Future[None]) -> None:
        # Until an owner is heard, the client hangs up, or the timeout.
        news = asyncio.ensure_future(self._owner_heard.wait())
        either: list[asyncio.Future[Any]] = [news, hung_up]
        try:
            await asyncio.wait(either, timeout=timeout, return_when=FIRST_COMPLETED)
        finally:
            news.cancel()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "lifespan":
            await self.app(scope, self._closing_on_shutdown(receive), send)
            return
        if scope["type"] != "http" or not _forwarded(scope["path"]) or self.here():
            await self.app(scope, receive, send)
            return
        self._loop = asyncio.get_running_loop()
        body = bytearray()
        while True:
            message: Message = await receive()
            body += message.get("body", b"")
            if not message.get("more_body", False):
                break
        await self._forward(scope, bytes(body), receive, send)

    async def _forward(self, scope: Scope, body: bytes, receive: Receive, send: Send) -> None:
        deadline = time.monotonic() + self.wait
        hung_up: asyncio.Future[None] | None = None  # watching the client, once it waits
        try:
            while True:
                if self.here():  # promoted while the request waited: this worker answers it
                    if hung_up is not None:  # the app hears the client from now on
                        hung_up.cancel()
                        await asyncio.wait([hung_up])
                    await self.app(scope, _replay(body, receive), send)
                    return
                owner = self.owner_url()
                if owner is not None and await self._sent(scope, owner, body, receive, send):
                    return
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                if hung_up is None:
                    # While the request waits, its client may hang up (a script's timeout,
                    # a closed tab): it is then dropped, never applied behind its back.
                    hung_up = asyncio.ensure_future(_hang_up(receive))
                await self._news_of_owner(min(left, ANNOUNCE_INTERVAL), hung_up)
                if hung_up.done():
                    return  # no one to answer
        finally:
            if hung_up is not None:
                hung_up.cancel()
        # A new owner is heard within an announcement of its start; trying again then waits
        # for it as this request did.
        response = error_response(
            503,
            f"no worker that owns the rigs could be reached for {self.wait:g} s",
            "rig_unavailable",
            headers={"Retry-After": str(math.ceil(ANNOUNCE_INTERVAL))},
        )
        await response(scope, receive, send)

    async def _sent(
        self, scope: Scope, owner: str, body: bytes, receive: Receive, send: Send
    ) -> bool:
        # Whether the request was sent to the owner (and answered, by it or by a 503).
        import httpx

        try:
            answer = await self._client.send(
                _request(self._client, scope, owner, body), stream=True
            )
        except (httpx.ConnectError, httpx.ConnectTimeout) as exc:
            why = f"{owner}: {exc or type(exc).__name__}"
            if why != self._unreachable:  # once per reason, not once per held request
                self._unreachable = why
                log.warning("cannot reach the worker that owns the rigs at %s", why)
            return False  # never sent: safe to send again, even a POST
        except httpx.HTTPError:
            # Sent, and no answer: the owner may have applied it; sending it again could
            # apply it twice (a second run started). The caller decides.
            response = error_response(
                503, "the worker that owns the rigs did not answer", "rig_unavailable"
            )
            await response(scope, receive, send)
            return True
        self._unreachable = ""
        await _relay(answer, send)
        return True


def _request(client: httpx.AsyncClient, scope: Scope, owner: str, body: bytes) -> httpx.Request:
    headers = [(k, v) for k, v in scope["headers"] if k.lower() not in _HOP_BY_HOP]
    query = scope.get("query_string", b"").decode("latin-1")
    url = owner.rstrip("/") + scope["raw_path"].decode("latin-1") + (f"?{query}" if query else "")
    return client.build_request(scope["method"], url, headers=headers, content=body)


async def _relay(answer: httpx.Response, send: Send) -> None:
    try:
        await send(
            {
                "type": "http.response.start",
                "status": answer.status_code,
                "headers": [(k, v) for k, v in answer.headers.raw if k.lower() not in _HOP_BY_HOP],
            }
        )
        async for chunk in answer.aiter_raw():
            await send({"type": "http.response.body", "body": chunk, "more_body": True})
        await send({"type": "http.response.body", "body": b"", "more_body": False})
    finally:
        await answer.aclose()


async def _hang_up(receive: Receive) -> None:
    # After the body, the server's next message for this request is its client hanging up.
    while (await receive())["type"] != "http.disconnect":
        pass


def _replay(body: bytes, receive: Receive) -> Receive:
    # The body was read for the owner; the app reads it again, then hears the client as usual.
    given = False

    async def replayed() -> Message:
        nonlocal given
        if given:
            return await receive()
        given = True
        return {"type": "http.request", "body": body, "more_body": False}

    return replayed
