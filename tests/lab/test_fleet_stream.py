"""One ``seq`` space for a fleet: a watcher moving between workers misses nothing, twice nothing.

Property (Hypothesis): the owner's channel publishes a rig's messages and
relays each, numbered and encoded, to followers' channels (as
:class:`~thermolab.lab.fleet.workers.Fleet` does over the bus), which may start
following at any point (an announcement of the owner's ``seq`` first, or
not). A watcher attached to one worker takes what it is sent, then at any
moment moves to another worker and resumes with the last ``seq`` it saw
(``replay_since`` and then what that worker publishes); whatever the
interleaving, it ends with every replayable message from where it started,
each once and in order. Channels are real; the bus is the in-process one.
"""

from __future__ import annotations

import json
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.lab.fleet.bus import LocalBus
from thermolab.lab.live.fanout import LiveChannel


def _fleet(followers: int, announce: bool) -> tuple[LiveChannel, list[LiveChannel]]:
    bus = LocalBus()
    owner = LiveChannel("twin", ring=10_000, seq_base=1_000_000)
    workers = [LiveChannel("twin", ring=10_000, seq_base=9_000_000) for _ in range(followers)]
    for worker in workers:
        if announce:
            worker.follow(owner.seq)
        bus.subscribe(
            "live",
            lambda data, w=worker: w.publish_numbered(json.loads(data), data.decode()),
        )
    owner.relay = lambda rig, text: bus.publish("live", text.encode())
    return owner, workers


@settings(max_examples=150, deadline=None)
@given(
    followers=st.integers(1, 3),
    announce=st.booleans(),
    before=st.integers(1, 30),
    plan=st.lists(
        st.tuples(st.integers(0, 20), st.integers(0, 3)),  # (messages published, move to)
        min_size=1,
        max_size=6,
    ),
)
def test_a_watcher_moving_between_workers_gets_every_message_once_in_order(
    followers: int, announce: bool, before: int, plan: list[tuple[int, int]]
) -> None:
    owner, workers = _fleet(followers, announce)
    everyone = [owner, *workers]
    k = 0

    def publish(count: int) -> None:
        nonlocal k
        for _ in range(count):
            owner.publish({"type": "sample", "run": 1, "k": k, "t": k, "u": 0.0, "y": 0.0})
            k += 1

    publish(before)
    # The watcher starts on a follower, after the messages so far: it saw the last one.
    at = workers[0]
    seen: list[dict[str, Any]] = [at.replay_since(at.seq - 1)[0][-1]]
    first = seen[0]["k"]
    for count, move in plan:
        published_from = at.seq
        publish(count)
        got, gap = at.replay_since(published_from)  # what this worker had for it meanwhile
        assert not gap
        seen += got
        at = everyone[move % len(everyone)]
        resumed, gap = at.replay_since(seen[-1]["seq"])  # reconnect with since
        assert not gap
        seen += resumed
    assert [m["k"] for m in seen] == list(range(first, k))
    seqs = [m["seq"] for m in seen]
    assert seqs == sorted(set(seqs))
    for worker in workers:  # one numbering: every worker holds the owner's numbers
        assert worker.seq == owner.seq
