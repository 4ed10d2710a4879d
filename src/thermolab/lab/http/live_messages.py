"""The live protocol's messages (contract: ``docs/live-protocol.md``).

Each message the live endpoint sends is one of these ``TypedDict`` shapes: the
type checker holds every builder to its fields, and the JSON is the dict as
is (no per-message model object on the hot path: one sample is encoded once
for every watcher). ``seq`` is added by the fan-out when a message is
published. :func:`client_message_type` reads the one message a client may
send (``ping``), within the size and nesting limits.
"""

from __future__ import annotations

import json
from typing import Any, Literal, TypedDict

from thermolab.lab.live.fanout import MAX_CLIENT_MESSAGE, MAX_CLIENT_NESTING

__all__ = [
    "AccessMessage",
    "ErrorMessage",
    "EstimateMessage",
    "HelloMessage",
    "RunMessage",
    "SampleItem",
    "SampleMessage",
    "SamplesMessage",
    "StateMessage",
    "TruncatedMessage",
    "client_message_type",
]


class SampleItem(TypedDict):
    """One sample: of run ``run`` (``k`` its index), or of idle monitoring (both null)."""

    run: int | None
    k: int | None
    t: float
    u: float | None
    y: float


class SampleMessage(SampleItem):
    """``sample``: every sample of a run, and of the idle monitoring of a powered rig.

    ``channels`` holds every channel of a run's sample by name
    (:meth:`thermolab.runner.SampleEvent.channels`: ``t,u,y,k,t_read,jitter,lateness``
    and any a rig adds: a kit's ``t2``, ``q2``); an idle reading has ``t``, ``u``, ``y``
    and the rig's further channels.
    """

    type: Literal["sample"]
    channels: dict[str, float | None]


class SamplesMessage(TypedDict, total=False):
    """``samples``: a replayed gap, in batches (``seq`` absent for samples from the store).

    An item from the store has ``run``, ``k``, ``t``, ``u``, ``y`` and, for a
    run with further channels (a kit's ``t2``, ``q2``), ``channels`` with those.
    """

    type: Literal["samples"]
    seq: int
    items: list[dict[str, Any]]


TruncatedMessage = TypedDict(
    "TruncatedMessage",
    {"type": Literal["truncated"], "run": int, "from": int, "limit": int},
)
"""``truncated``: a replay from the store skipped samples of run ``run``.

Sent after the run's first sample and before its newest ones, which start at
sample ``from``; ``limit`` is the most stored samples one socket is sent.
(Functional form: ``from`` is a Python keyword.)
"""


class EstimateMessage(TypedDict):
    """``estimate``: an identifier produced an estimate (``reason``: why no model, else null)."""

    type: Literal["estimate"]
    run: int
    method: str
    k: int
    K: float | None
    tau: float | None
    W: list[float] | None
    valid: bool | None
    final: bool
    reason: str | None


class RunMessage(TypedDict):
    """``run``: START / END / fault; ``run`` as ``GET /api/runs/{run}``."""

    type: Literal["run"]
    event: Literal["started", "ended"]
    run: dict[str, Any]


class AccessMessage(TypedDict):
    """``access``: the rig's access as this client sees it."""

    type: Literal["access"]
    access: dict[str, Any]


class StateMessage(TypedDict):
    """``state``: the rig's state changed."""

    type: Literal["state"]
    state: str
    detail: str | None


class HelloMessage(TypedDict):
    """``hello``: the first message after connecting."""

    type: Literal["hello"]
    rig: dict[str, Any]
    access: dict[str, Any]
    run: dict[str, Any] | None
    seq: int


class ErrorMessage(TypedDict):
    """``error``: a malformed client message (the connection stays open)."""

    type: Literal["error"]
    detail: str


# -- client -> server ---------------------------------------------------------------------


def client_message_type(text: str) -> str:
    """``"ping"`` for a ping, else the problem with the message, in words.

    Examples
    --------
    >>> client_message_type('{"type": "ping"}')
    'ping'
    >>> client_message_type("[" * 100)
    'messages nest at most 8 levels of brackets'
    """
    if len(text) > MAX_CLIENT_MESSAGE:
        return f"messages are at most {MAX_CLIENT_MESSAGE} bytes"
    if _nesting(text) > MAX_CLIENT_NESTING:
        # json.loads recurses once per level: a few kB of brackets would overflow the stack.
        return f"messages nest at most {MAX_CLIENT_NESTING} levels of brackets"
    try:
        data = json.loads(text)
    except ValueError:
        return 'messages must be JSON objects such as {"type": "ping"}'
    if not isinstance(data, dict):
        return 'messages must be JSON objects such as {"type": "ping"}'
    kind = data.get("type")
    if kind == "ping":
        return "ping"
    return (
        f"unknown message type {kind!r}; the only one is 'ping' (commands go through the HTTP API)"
    )


def _nesting(text: str) -> int:
    """The deepest nesting of ``[``/``{`` in ``text`` outside JSON strings (linear, no recursion).

    >>> _nesting('{"a": [1, {"b": "[[["}]}')
    3
    """
    depth = deepest = 0
    in_string = escaped = False
    for char in text:
        if in_string:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth -= 1
    return deepest
