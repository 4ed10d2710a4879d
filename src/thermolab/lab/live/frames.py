"""A WebSocket connection written to directly: the frame, and the writer a server offers.

The live stream (:mod:`~thermolab.lab.live.fanout`) builds each batch's frame once
(:func:`text_frame`) and, where the server puts a :class:`FrameWriter` in the
ASGI scope's extensions under :data:`FRAMES_EXTENSION` (``thermolab serve``'s
uvicorn protocol, :mod:`thermolab.cli.serve`), writes those same bytes to
every caught-up client's socket.
"""

from __future__ import annotations

from typing import Protocol

__all__ = ["FRAMES_EXTENSION", "MAX_UNSENT_BYTES", "FrameWriter", "text_frame"]

FRAMES_EXTENSION = "thermolab.frames"
"""The ASGI scope extension under which a server offers its socket's :class:`FrameWriter`."""
MAX_UNSENT_BYTES = 1 << 20
"""A client written to directly is cut when its socket holds more than this unsent."""


class FrameWriter(Protocol):
    """A WebSocket connection's socket, written to without the ASGI ``send`` (loop thread).

    The server that offers it (``thermolab serve``'s uvicorn protocol) keeps
    the connection's own frames (handshake, pings, close) in order with these
    writes: both go to the same transport, from the same thread.
    """

    def write(self, frame: bytes) -> bool:
        """Write one whole frame; ``False`` (nothing written) once the connection is closing."""

    def buffered(self) -> int:
        """Bytes written but not yet taken by the socket."""


def text_frame(payload: bytes) -> bytes:
    """Return ``payload`` as one unmasked, final WebSocket text frame (RFC 6455, 5.2).

    Examples
    --------
    >>> text_frame(b"hi")
    b'\\x81\\x02hi'
    >>> text_frame(b"x" * 200)[:4]
    b'\\x81~\\x00\\xc8'
    """
    size = len(payload)
    if size < 126:
        head = bytes((0x81, size))
    elif size < 1 << 16:
        head = bytes((0x81, 126)) + size.to_bytes(2, "big")
    else:
        head = bytes((0x81, 127)) + size.to_bytes(8, "big")
    return head + payload
