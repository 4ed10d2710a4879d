"""Who watches a rig, counted over several workers sharing one real Redis (issue #14).

Two or three :class:`SharedPresence` on one Redis stand for web workers: a
watcher on one counts on the others, once however many workers they are on
(connections added up), leaves as the in-memory presence would (at once
when still connected elsewhere, a timeout after their last contact), and a
worker that stops refreshing (killed) stops counting when its hash expires.
Skipped, with the reason, where Redis is absent.
"""

from __future__ import annotations

from typing import Any

import pytest

from thermolab.lab.clock import SystemClock
from thermolab.lab.fleet.worker_hashes import figures_client
from thermolab.lab.live.presence import Presence
from thermolab.lab.live.shared_presence import SharedPresence

from .test_shared_limits import until

pytestmark = pytest.mark.redis

FAST: dict[str, float] = {"refresh": 0.2, "ttl": 1.0, "gap": 0.05, "poll": 0.1}


def seen(presence: Presence, rig_id: str = "twin") -> list[tuple[str, int]]:
    return [(w.username, w.connections) for w in presence.watchers(rig_id)]


def test_each_worker_counts_the_others_watchers_once_per_person(redis: Any, prefix: str) -> None:
    workers = [Presence(SystemClock(), timeout=0.8) for _ in range(3)]
    shared = [SharedPresence(presence, redis, prefix, **FAST) for presence in workers]
    first, second, third = workers
    heard: list[str] = []
    third.on_elsewhere(heard.append)
    try:
        ana = first.connect("twin", "ana")
        second.connect("twin", "ana")  # a second tab, on another worker
        second.connect("twin", "bo")
        first.touch("other", "cy")  # a page polling another rig
        assert until(lambda: seen(third) == [("ana", 2), ("bo", 1)], within=1.0) < 1.0
        assert "twin" in heard  # the live stream is told to send the access again
        assert seen(first) == [("ana", 2), ("bo", 1)]  # its own, exact, and the other's
        assert seen(third, "other") == [("cy", 0)]
        assert [w.username for w in first.here("twin")["twin"]] == ["ana"]  # its own alone
        # Ana closes one tab: still watching (on the second worker) and counted once.
        first.disconnect(ana)
        until(lambda: seen(third) == [("ana", 1), ("bo", 1)], within=1.0)
        # Cy stopped polling: gone a timeout after the last request, as on one worker.
        until(lambda: seen(third, "other") == [], within=1.5)
        # A worker that stops cleanly takes its watchers out at once...
        shared[1].close()
        assert until(lambda: ("bo", 1) not in seen(third), within=0.5) < 0.5
        until(lambda: seen(third) == [], within=1.5)  # ana's closed tab, once timed out
        heard.clear()
        second_tab = first.connect("twin", "di")
        until(lambda: seen(third) == [("di", 1)], within=1.0)
        assert "twin" in heard
        # ... and one that stops refreshing (killed) when its hash expires.
        shared[0].halt()
        assert seen(third) == [("di", 1)]
        waited = until(lambda: seen(third) == [], within=3.0)
        assert waited > 0.3
        first.disconnect(second_tab)
    finally:
        for sharing in shared:
            sharing.close()


def test_without_redis_a_worker_counts_its_own_watchers() -> None:
    presence = Presence(SystemClock(), timeout=15)
    shared = SharedPresence(presence, figures_client("redis://127.0.0.1:1/0"), "x.", poll=0.05)
    try:
        presence.connect("twin", "ana")
        shared.read()
        assert seen(presence) == [("ana", 1)]
    finally:
        shared.close()
