"""The lab's HTTP server: uvicorn, bounded (issue #13).

uvicorn runs the pure-Python h11 parser, whose incomplete-event bound refuses
request heads over 16 KiB (httptools, which uvicorn picks by default, has
none); a client has ``request_timeout`` seconds to send a whole request, and a
new connection three times that to begin one (a slow or silent client is cut,
:func:`_bounded_h11`); a WebSocket frame over
1 MiB is refused from its header (:data:`WS_MAX_SIZE`); an idle keep-alive
connection is closed after 5 s; beyond 1000 open connections (``thermolab
serve --max-connections``) new requests get 503. The live stream writes its
ready-made frames straight to each socket (:func:`_framed_websockets`). A
storm of WebSocket upgrades goes through the event loop's
:mod:`~thermolab.lab.live.turnstile` a few per turn.
"""

from __future__ import annotations

import asyncio
from typing import Any

__all__ = ["CONNECTION_LIMIT", "HEAD_LIMIT", "KEEP_ALIVE_TIMEOUT", "WS_MAX_SIZE", "run_server"]

HEAD_LIMIT = 16 * 1024
"""Largest request head (request line and headers) in bytes; larger ones are refused."""
KEEP_ALIVE_TIMEOUT = 5
"""Seconds an idle keep-alive connection stays open."""
SILENT_CONNECTION_FACTOR = 3
"""A new connection that sends nothing is cut after this many request timeouts."""
CONNECTION_LIMIT = 1000
"""Open connections (HTTP and WebSocket) beyond which new requests get 503."""
WS_MAX_SIZE = 2**20
"""Largest WebSocket message read: a bigger frame is refused from its header (close 1009).

A live client's messages are refused over 4 KiB by the lab itself; rig hosts'
messages, on the same server, stay under the 1 MiB their own end accepts.
"""


def _bounded_h11(request_timeout: float) -> type[asyncio.Protocol]:
    """uvicorn's h11 protocol, cutting a client that takes too long to send a request.

    uvicorn bounds the wait between requests (keep-alive) but not the wait for
    a request: a client that sends a head byte by byte (slowloris), a body
    slowly, or nothing at all would hold its connection forever. The timer
    runs from the connection (or the first byte of the next request) until the
    whole request is in.
    """
    import h11
    from uvicorn.protocols.http.h11_impl import H11Protocol

    from thermolab.lab.live.turnstile import loop_turnstile

    class BoundedH11Protocol(H11Protocol):
        _request_timer: asyncio.TimerHandle | None = None
        _upgraded = False
        _silent = True  # nothing received yet
        _turn: asyncio.Future[None] | None = None  # the upgrade's place in the loop's turnstile

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            # A connection that has sent nothing yet may be a browser's, opened ahead of
            # its requests: Chromium keeps such a socket unused up to 10 s and sends on it
            # without retrying if it was cut. Cut at the same moment (the default request
            # time), a page's module failed to load now and then; it gets three times that.
            self._arm(SILENT_CONNECTION_FACTOR * request_timeout)

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if self._upgraded:
                # The WebSocket protocol owns the connection now; h11 still reads the
                # upgrade request as SEND_BODY, and a timer armed here cut every live
                # socket after request_timeout seconds.
                return
            if self.conn.their_state in (h11.IDLE, h11.SEND_BODY):
                # A request has begun: it must end in time (the silent allowance is over).
                self._arm(only_if_unarmed=not self._silent)
                self._silent = False
            else:
                self._disarm()

        def connection_lost(self, exc: Exception | None) -> None:
            self._disarm()
            if self._turn is not None:
                self._turn.cancel()  # its place goes to the next connection
            super().connection_lost(exc)

        def handle_websocket_upgrade(self, event: h11.Request) -> None:
            self._upgraded = True
            self._disarm()
            # A lecture hall reconnecting sends a thousand upgrade requests at once, and
            # the event loop reads them all in one go: their handshakes (the request parsed
            # again, the accept key, the WebSocket protocol) held the live stream's samples
            # for all of them. A few are upgraded per turn of the loop; the others wait,
            # unread (a client sends nothing more before its handshake's answer).
            self._turn = loop_turnstile().place()
            if self._turn is None:
                super().handle_websocket_upgrade(event)
                return
            self.transport.pause_reading()
            self._turn.add_done_callback(lambda turn: self._upgrade_now(turn, event))

        def _upgrade_now(self, turn: asyncio.Future[None], event: h11.Request) -> None:
            self._turn = None
            if turn.cancelled() or self.transport.is_closing():
                return
            self.transport.resume_reading()
            super().handle_websocket_upgrade(event)

        def _arm(self, seconds: float = request_timeout, *, only_if_unarmed: bool = False) -> None:
            if only_if_unarmed and self._request_timer is not None:
                return
            self._disarm()
            self._request_timer = self.loop.call_later(seconds, self._too_slow)

        def _disarm(self) -> None:
            if self._request_timer is not None:
                self._request_timer.cancel()
                self._request_timer = None

        def _too_slow(self) -> None:
            self._request_timer = None
            if (
                self.conn.their_state in (h11.IDLE, h11.SEND_BODY)
                and not self.transport.is_closing()
            ):
                self.logger.info("closed a connection that was too slow to send its request")
                self.transport.close()

    return BoundedH11Protocol


def _framed_websockets() -> type[asyncio.Protocol]:
    """uvicorn's WebSocket protocol, offering the live stream direct writes to its socket.

    The ASGI scope gets :data:`~thermolab.lab.live.fanout.FRAMES_EXTENSION`: a
    writer that puts a whole, ready-made frame on the connection's transport
    (the frame the channel built once for every client). The protocol's own
    frames (pings, close) go to the same transport from the same thread, so
    frames never interleave; nothing is written once a close is sent. Joiners
    pass the loop's :mod:`~thermolab.lab.live.turnstile` before the app sees them.
    """
    from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol
    from websockets.http11 import Request

    from thermolab.lab.live.fanout import FRAMES_EXTENSION
    from thermolab.lab.live.turnstile import take_turn

    class Frames:
        __slots__ = ("protocol",)

        def __init__(self, protocol: WebSocketsSansIOProtocol) -> None:
            self.protocol = protocol

        def write(self, frame: bytes) -> bool:
            protocol = self.protocol
            transport = protocol.transport
            if protocol.close_sent or transport.is_closing():
                return False
            transport.write(frame)
            return True

        def buffered(self) -> int:
            size: int = self.protocol.transport.get_write_buffer_size()
            return size

    class FramedWebSockets(WebSocketsSansIOProtocol):
        def handle_connect(self, event: Request) -> None:
            super().handle_connect(event)
            scope = getattr(self, "scope", None)  # none when the handshake was refused
            if scope is not None:
                scope["extensions"][FRAMES_EXTENSION] = Frames(self)

        async def run_asgi(self) -> None:
            # A thousand pages joining at once would each run the whole ASGI stack
            # (middleware, routing, the accept) in the same turn of the loop, and a
            # sample's flush would wait behind them all: a few go through per turn.
            await take_turn()
            await super().run_asgi()

    return FramedWebSockets


def run_server(
    app: Any,
    host: str,
    port: int,
    *,
    request_timeout: float = 10.0,
    tls: tuple[str | None, str | None] = (None, None),
    max_connections: int = CONNECTION_LIMIT,
    log_format: str = "text",
) -> None:
    """Serve ``app`` with uvicorn, bounded as this module's docstring says."""
    import uvicorn

    from thermolab.lab.operations.logs import log_config

    logging_config = log_config("json" if log_format == "json" else "text")
    # uvicorn's default (its coloured text) unless JSON lines were asked for.
    logging: Any = uvicorn.config.LOGGING_CONFIG if logging_config is None else logging_config

    # Live messages are small and go to many clients: compressing each one for each
    # client (permessage-deflate keeps a context per connection) cost the server more
    # than everything else in sending them (benchmarks/bench_live.py).
    uvicorn.run(
        app,
        host=host,
        port=port,
        log_level="info",
        log_config=logging,
        # X-Forwarded-For is believed only from access.trusted_proxies, in the app itself
        # (uvicorn's default would trust any proxy on 127.0.0.1).
        proxy_headers=False,
        ws_per_message_deflate=False,
        ws_max_size=WS_MAX_SIZE,
        http=_bounded_h11(request_timeout),
        ws=_framed_websockets(),
        h11_max_incomplete_event_size=HEAD_LIMIT,
        timeout_keep_alive=KEEP_ALIVE_TIMEOUT,
        limit_concurrency=max_connections,
        # TLS (wss:// for rig hosts): uvicorn's own, with the certificate given.
        ssl_certfile=tls[0],
        ssl_keyfile=tls[1],
    )
