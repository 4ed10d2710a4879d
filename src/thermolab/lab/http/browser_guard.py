"""Browser-side protections: same-origin checks (CSRF) and security headers.

:class:`BrowserGuard` is a plain ASGI middleware (no request body is read):

* **CSRF** (ASVS 4.0 V4.2.2, V13.2.3). A state-changing request (POST, PUT,
  PATCH, DELETE, body or not) and the live WebSocket's handshake must come
  from the lab's own pages. Browsers say where a request comes from: with
  ``Sec-Fetch-Site`` (Fetch Metadata), only ``same-origin`` and ``none`` (typed
  by the user) pass; without it, an ``Origin`` header must name the host the
  request was sent to. A refused request gets 403 ``{"code": "cross_origin"}``;
  a refused handshake is closed before it is accepted (HTTP 403). A request
  with neither header is not from a browser page (``curl``, scripts), which
  cannot carry a victim's cookie, so it passes. The SameSite=Strict cookie is
  the second line of defence. A request with an ``Authorization`` header
  passes too: it is a script's (a personal API token), judged by that header
  alone and never by a cookie sent along (``http/credentials``), and a
  browser never adds the header by itself — a page on another site would
  have to know the token, and its cross-origin fetch with that header needs a
  CORS preflight the lab never grants.
* **Headers** on every answer: a strict Content-Security-Policy (scripts and
  styles only from the lab itself: the page has no inline script, and must
  keep it so), ``frame-ancestors`` from ``access.frame_ancestors`` (default
  ``'self'``: clickjacking), ``X-Content-Type-Options: nosniff``,
  ``Referrer-Policy: same-origin``, and ``Cache-Control: no-store`` on the API
  and its schema (answers carry personal data and session state) — except
  that an answer under one of ``cacheable_prefixes`` that brings its own
  ``Cache-Control`` keeps it (a guide's pictures, which never change).

The API docs pages (``/docs``, ``/redoc``) get the same policy except that
their renderers need inline *styles* and a worker from ``blob:``; scripts stay
``'self'`` only (see :mod:`thermolab.lab.http.api_docs`).

Hand-written: the checks are a few lines over the ASGI scope, and no
well-kept package does Fetch-Metadata + Origin for both HTTP and WebSocket.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from urllib.parse import urlsplit

from starlette.requests import HTTPConnection
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from thermolab.lab.error_messages import LANGUAGE_COOKIE, error_message, negotiate_language

__all__ = ["BrowserGuard", "content_security_policy", "is_same_origin"]

_STATE_CHANGING = frozenset({"POST", "PUT", "PATCH", "DELETE"})
_DOCS_PATHS = ("/docs", "/redoc")
_NO_STORE_PREFIXES = ("/api/", "/openapi.json")
_DEFAULT_PORTS = {"http": 80, "https": 443, "ws": 80, "wss": 443}


def content_security_policy(frame_ancestors: Iterable[str], *, docs: bool = False) -> str:
    """Return the Content-Security-Policy header value.

    Parameters
    ----------
    frame_ancestors : iterable of str
        Sources allowed to frame the lab (``'self'``, ``https://lms.example``).
    docs : bool
        The policy of the API docs pages (inline styles and ``blob:`` workers).

    Examples
    --------
    >>> policy = content_security_policy(["'self'"])
    >>> "script-src 'self'" in policy and "frame-ancestors 'self'" in policy
    True
    >>> "unsafe-inline" in policy
    False
    """
    style = "'self' 'unsafe-inline'" if docs else "'self'"
    parts = [
        "default-src 'self'",
        "script-src 'self'",
        f"style-src {style}",
        "img-src 'self' data: blob:",
        "connect-src 'self'",
        "font-src 'self'",
        "object-src 'none'",
        "base-uri 'self'",
        "form-action 'self'",
        f"frame-ancestors {' '.join(frame_ancestors) or chr(39) + 'none' + chr(39)}",
    ]
    if docs:
        parts.append("worker-src 'self' blob:")
    return "; ".join(parts)


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            return str(value.decode("latin-1"))
    return None


def _netloc(scheme: str, host: str) -> str:
    """``host[:port]`` in lower case, without the scheme's default port."""
    parts = urlsplit(f"//{host.strip().lower()}")
    try:
        port = parts.port
    except ValueError:
        return host.strip().lower()
    name = parts.hostname or ""
    if ":" in name:
        name = f"[{name}]"
    if port is None or port == _DEFAULT_PORTS.get(scheme):
        return name
    return f"{name}:{port}"


def is_same_origin(scope: Scope) -> bool:
    """Whether a request or handshake comes from the lab's own pages (or not from a page).

    A request with an ``Authorization`` header (a script's API token) passes:
    it is authenticated by that header alone, never by a cookie.

    Examples
    --------
    >>> scope = {"scheme": "http", "headers": [(b"host", b"lab:8000"),
    ...                                        (b"origin", b"http://lab:8000")]}
    >>> is_same_origin(scope)
    True
    >>> scope["headers"][1] = (b"origin", b"https://evil.example")
    >>> is_same_origin(scope)
    False
    >>> is_same_origin({"scheme": "http", "headers": [(b"sec-fetch-site", b"cross-site")]})
    False
    >>> is_same_origin({"scheme": "http", "headers": [(b"sec-fetch-site", b"cross-site"),
    ...                                               (b"authorization", b"Bearer tlab_x")]})
    True
    """
    if _header(scope, b"authorization") is not None:
        return True  # a bearer request: authenticated by its token alone, never the cookie
    site = _header(scope, b"sec-fetch-site")
    if site is not None:
        return site.strip().lower() in ("same-origin", "none")
    origin = _header(scope, b"origin")
    if origin is None:
        return True
    parts = urlsplit(origin.strip())
    host = _header(scope, b"host")
    if not parts.scheme or not parts.netloc or host is None:
        return False  # "null" (sandboxed frame, file:) or nothing to compare with
    return _netloc(parts.scheme, parts.netloc) == _netloc(str(scope.get("scheme", "http")), host)


class BrowserGuard:
    """ASGI middleware: refuse cross-origin state changes, add security headers.

    Parameters
    ----------
    app : ASGIApp
        The application to guard.
    frame_ancestors : iterable of str
        CSP ``frame-ancestors`` sources.
    more_ancestors : callable, optional
        More sources, asked on each request (the registered LTI platforms,
        which frame the lab in their course pages).
    cross_site_paths : iterable of str
        Paths a page of another site may POST to: the LTI login and launch,
        authenticated by the platform's signed token, never by a cookie.
    cacheable_prefixes : iterable of str
        API paths whose answers may say how long they are cached (their own
        ``Cache-Control``); any other API answer is ``no-store``.

    A response that brings its own Content-Security-Policy keeps it (the
    LTI deep-linking answer posts a form to the platform).
    """

    def __init__(
        self,
        app: ASGIApp,
        *,
        frame_ancestors: Iterable[str] = ("'self'",),
        more_ancestors: Callable[[], tuple[str, ...]] | None = None,
        cross_site_paths: Iterable[str] = (),
        cacheable_prefixes: Iterable[str] = (),
    ) -> None:
        self.app = app
        self._base = tuple(frame_ancestors)
        self._more = more_ancestors
        self._cross_site = frozenset(cross_site_paths)
        self._cacheable = tuple(cacheable_prefixes)
        self._ancestors: tuple[str, ...] | None = None
        self._policies(self._base)

    def _policies(self, ancestors: tuple[str, ...]) -> None:
        if ancestors == self._ancestors:
            return
        self._headers = [
            (b"x-content-type-options", b"nosniff"),
            (b"referrer-policy", b"same-origin"),
            (b"cross-origin-opener-policy", b"same-origin"),
        ]
        if ancestors == ("'self'",):
            self._headers.append((b"x-frame-options", b"SAMEORIGIN"))  # browsers without CSP 2
        self._csp = content_security_policy(ancestors).encode("latin-1")
        self._docs_csp = content_security_policy(ancestors, docs=True).encode("latin-1")
        self._ancestors = ancestors

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "websocket":
            if not is_same_origin(scope):
                await receive()  # the websocket.connect message
                await send({"type": "websocket.close", "code": 1008})  # HTTP 403 before accept
                return
            await self.app(scope, receive, send)
            return
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path: str = scope.get("path", "")
        if (
            scope.get("method", "GET").upper() in _STATE_CHANGING
            and path not in self._cross_site
            and not is_same_origin(scope)
        ):
            await self._refuse(scope, send)
            return
        if self._more is not None:
            more = self._more()
            self._policies(self._base + tuple(o for o in more if o not in self._base))
        csp = self._docs_csp if path.startswith(_DOCS_PATHS) else self._csp
        no_store = path.startswith(_NO_STORE_PREFIXES)
        may_cache = bool(self._cacheable) and path.startswith(self._cacheable)
        extra = [*self._headers, (b"content-security-policy", csp)]

        async def send_with_headers(message: Message) -> None:
            nonlocal no_store
            if message["type"] == "http.response.start":
                given = message.get("headers", ())
                if may_cache and any(k.lower() == b"cache-control" for k, _ in given):
                    no_store = False
                headers = [
                    (k, v) for k, v in given if not (no_store and k.lower() == b"cache-control")
                ]
                own = any(k.lower() == b"content-security-policy" for k, _ in headers)
                headers += [h for h in extra if not (own and h[0] == b"content-security-policy")]
                if no_store:
                    headers.append((b"cache-control", b"no-store"))
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with_headers)

    async def _refuse(self, scope: Scope, send: Send) -> None:
        connection = HTTPConnection(scope)
        language = negotiate_language(
            connection.headers.get("accept-language"), connection.cookies.get(LANGUAGE_COOKIE)
        )
        body = json.dumps(
            {
                "detail": "cross-origin request refused: state-changing requests must come "
                "from the lab's own pages (Origin / Sec-Fetch-Site)",
                "code": "cross_origin",
                "message": error_message("cross_origin", language),
            }
        ).encode("utf-8")
        await send(
            {
                "type": "http.response.start",
                "status": 403,
                "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-language", language.encode("ascii")),
                    (b"content-length", str(len(body)).encode("ascii")),
                    (b"cache-control", b"no-store"),
                    *self._headers,
                    (b"content-security-policy", self._csp),
                ],
            }
        )
        await send({"type": "http.response.body", "body": body})
