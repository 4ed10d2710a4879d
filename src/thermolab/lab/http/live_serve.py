"""One live client's connection once it is attached: send its stream, read its pings.

The sender takes the client's queue through the ASGI ``send`` until it has
caught up (``hello`` and any replay went first), then — where the server
offers a :class:`~thermolab.lab.live.fanout.FrameWriter` in the scope's
:data:`~thermolab.lab.live.fanout.FRAMES_EXTENSION` — hands the client to the
channel for direct writes: from then on a batch costs this client one socket
write, made by the channel's flush, and the sender only waits for the end.

A ``ping`` is answered with ``pong`` once noted; what it keeps alive (presence,
a control or queue place) is the caller's ``on_ping``, a coroutine that does
its own scheduling (plain watchers' pings never leave the event loop).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Awaitable, Callable

from starlette.websockets import WebSocket, WebSocketDisconnect, WebSocketState

from thermolab.lab.http.live_messages import ErrorMessage, client_message_type
from thermolab.lab.live.fanout import FRAMES_EXTENSION, FrameWriter, LiveClient, encode

__all__ = ["CLOSE_TIMEOUT", "frame_writer", "serve_client"]

CLOSE_TIMEOUT = 10.0
"""Seconds a close frame may wait for a stalled socket to drain."""

_PONG = '{"type":"pong"}'


def frame_writer(websocket: WebSocket) -> FrameWriter | None:
    """The server's direct writer for this connection, if it offers one."""
    extensions = websocket.scope.get("extensions") or {}
    writer: FrameWriter | None = extensions.get(FRAMES_EXTENSION)
    return writer


async def serve_client(
    websocket: WebSocket,
    client: LiveClient,
    on_ping: Callable[[], Awaitable[None]],
    leave: Callable[[], None],
) -> None:
    """Send the client's stream and read its messages until either side stops (then ``leave``)."""
    writer = frame_writer(websocket)

    async def send() -> None:
        while client.closing is None:
            # Everything queued goes in one frame: a client that fell behind catches up
            # in one send instead of one per message.
            while (frame := client.next_frame()) is not None:
                await websocket.send_text(frame)
                client.sent += 1
            if writer is not None and client.go_direct(writer):
                await client.ended.wait()  # the channel writes from now on
                return
            await client.wake.wait()
            client.wake.clear()

    async def receive() -> None:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            if text is None:
                text = (message.get("bytes") or b"").decode("utf-8", errors="replace")
            # An oversized or over-deep message is answered like any bad message: the
            # socket stays open (a client's mistake is not a reason to cut its stream).
            kind = client_message_type(text)
            if kind == "ping":
                await on_ping()
                client.offer(_PONG)
            else:
                error: ErrorMessage = {"type": "error", "detail": kind}
                client.offer(encode(error))

    # The client being cut ends the connection at once, even while a send waits for a
    # stalled socket to drain (the send is abandoned; nothing of it was written).
    tasks = [
        asyncio.ensure_future(send()),
        asyncio.ensure_future(receive()),
        asyncio.ensure_future(client.ended.wait()),
    ]
    try:
        done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        for task in done:
            exc = task.exception()
            if exc is not None and not isinstance(exc, WebSocketDisconnect):
                raise exc
    finally:
        client.direct = None  # nothing more is written past the close frame
        for task in tasks:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(BaseException):
                await task
        leave()
        if (
            websocket.client_state is WebSocketState.CONNECTED
            and websocket.application_state is WebSocketState.CONNECTED
        ):
            code, reason = client.closing or (1000, "")
            # The close frame waits behind what the socket still holds; a peer that never
            # reads again is left to the server, which closes the connection.
            with contextlib.suppress(Exception):
                await asyncio.wait_for(websocket.close(code, reason), CLOSE_TIMEOUT)
