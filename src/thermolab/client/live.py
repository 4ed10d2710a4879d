"""Following a rig's live stream from a script (``docs/live-protocol.md``).

:func:`follow_run` opens the rig's WebSocket with the client's API token
(``Authorization: Bearer`` on the handshake), and yields the run's messages
(``sample``, ``estimate``, ``run``) as they come until the run ends. The
socket's close codes become clear errors: 4401 (token revoked or expired),
4404 (no such rig), 4429 (too many sockets for this token).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from thermolab.client.errors import LabRequestError

__all__ = ["follow_run", "live_url"]

_CLOSE_REASONS = {
    4401: ("not_authenticated", "the API token was revoked or expired"),
    4404: ("not_found", "no such rig"),
    4429: ("too_many_sockets", "this token already holds the most live sockets allowed"),
}


def live_url(base_url: str, rig_id: str, since: int | None = None) -> str:
    """The WebSocket URL of a rig's live stream.

    Examples
    --------
    >>> live_url("https://lab.example.edu/", "kit-1", since=7)
    'wss://lab.example.edu/api/rigs/kit-1/live?since=7'
    """
    scheme, rest = base_url.rstrip("/").split("://", 1)
    ws = {"http": "ws", "https": "wss"}.get(scheme, scheme)
    query = f"?since={since}" if since is not None else ""
    return f"{ws}://{rest}/api/rigs/{rig_id}/live{query}"


def _messages(frame: str | bytes) -> list[dict[str, Any]]:
    decoded = json.loads(frame)
    if isinstance(decoded, list):
        return [m for m in decoded if isinstance(m, dict)]
    return [decoded] if isinstance(decoded, dict) else []


def follow_run(
    base_url: str,
    token: str | None,
    rig_id: str,
    run_id: int | None = None,
    *,
    timeout: float | None = 60.0,
) -> Iterator[dict[str, Any]]:
    """Yield a run's messages until it ends (the ``run`` message ``ended`` is the last).

    Samples come once each, in order, from the first (a run already going is
    replayed from its start); estimates as they are made from then on.

    Parameters
    ----------
    base_url, token : str
        The lab and the API token.
    rig_id : str
    run_id : int, optional
        The run to follow; by default the rig's current one (or the next to start).
    timeout : float or None
        Seconds to wait for any message before giving up (``None``: forever).

    Raises
    ------
    LabRequestError
        When the lab closes the socket (token revoked, unknown rig) or is silent too long.
    """
    headers = {"authorization": f"Bearer {token}"} if token else {}
    # A run asked for by number may have started already: ``since=0`` makes the lab
    # replay what it holds of the current run first (from memory or its store).
    url = live_url(base_url, rig_id, since=0 if run_id is not None else None)
    last_k = -1
    try:
        socket = connect(url, additional_headers=headers, open_timeout=timeout)
    except (OSError, TimeoutError) as exc:
        raise LabRequestError("GET", url, None, "unreachable", str(exc)) from exc
    with socket:
        try:
            while True:
                try:
                    frame = socket.recv(timeout=timeout)
                except TimeoutError:
                    raise LabRequestError(
                        "GET", url, None, "timeout", f"no message for {timeout} s"
                    ) from None
                for message in _messages(frame):
                    kind = message.get("type")
                    if kind == "hello":
                        current = message.get("run")
                        if run_id is None and isinstance(current, dict):
                            run_id = int(current["id"])
                        continue
                    if kind == "run" and run_id is None and message.get("event") == "started":
                        run_id = int(message["run"]["id"])
                    if kind == "samples":  # a replayed batch
                        for item in message.get("items") or []:
                            if item.get("run") == run_id and int(item["k"]) > last_k:
                                last_k = int(item["k"])
                                yield {"type": "sample", **item}
                    elif kind == "sample" and run_id is not None and message.get("run") == run_id:
                        if int(message["k"]) > last_k:  # a replay and the live stream overlap
                            last_k = int(message["k"])
                            yield message
                    elif kind == "estimate" and run_id is not None and message.get("run") == run_id:
                        yield message
                    elif kind == "run" and message["run"].get("id") == run_id:
                        yield message
                        if message.get("event") == "ended":
                            return
        except ConnectionClosed as closed:
            close = closed.rcvd
            code = close.code if close is not None else 1006
            name, reason = _CLOSE_REASONS.get(code, ("closed", f"the lab closed it ({code})"))
            detail = close.reason if close is not None and close.reason else reason
            raise LabRequestError("GET", url, code, name, detail) from None
