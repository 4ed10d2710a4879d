"""Watchers on every worker count on the rig's page (issue #14), with real web workers.

Two ``thermolab serve --broker redis://...`` processes on one PostgreSQL
schema (:mod:`thermolab.lab.fleet.workers`), real HTTP and WebSockets: a student's
live socket on the follower counts in the owner's ``GET /api/rigs/twin``
(``access.watchers``, the teacher's ``watcherList``) and in the access
messages the owner's live sockets get; one person on both workers counts
once; closed, the socket stops counting once the client timeout has passed,
as on a lone server. Skipped, with the reason, where PostgreSQL or Redis is
absent.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from websockets.sync.client import ClientConnection, connect

from .fleet_setup import PEOPLE, seed_lab, stop
from .test_workers import Worker, _frames, _start

pytestmark = [pytest.mark.postgres, pytest.mark.redis, pytest.mark.slow]

TIMEOUT = 3.0  # s: the client timeout, after which a closed socket's user stops watching

WATCHERS_TOML = f"""
[access]
client_timeout = {TIMEOUT}

[rig_defaults]
idle_limit = 0

[[rigs]]
id = "twin"
title = "Twin"
spec = "sim:paper-practical"
"""


@pytest.fixture
def workers(tmp_path: Path, postgres_url: str, redis_url: str) -> Iterator[dict[str, Any]]:
    cookies = seed_lab(tmp_path, postgres_url, WATCHERS_TOML, PEOPLE)
    started = [_start(tmp_path, postgres_url, redis_url)]
    try:
        started.append(_start(tmp_path, postgres_url, redis_url))
        yield {"owner": started[0], "follower": started[1], "cookies": cookies}
    finally:
        stop([worker.process for worker in started])


@contextlib.contextmanager
def watching(worker: Worker, cookie: str) -> Iterator[ClientConnection]:
    """A live socket on ``worker``'s ``twin``, past its hello."""
    with connect(worker.ws + "/api/rigs/twin/live", additional_headers={"Cookie": cookie}) as ws:
        assert _frames(ws, 10)[0]["type"] == "hello"
        yield ws


def rig_page(worker: Worker, cookie: str) -> dict[str, Any]:
    answer = httpx.get(worker.base + "/api/rigs/twin", headers={"Cookie": cookie}, timeout=30)
    assert answer.status_code == 200, answer.text
    page: dict[str, Any] = answer.json()
    return page


def watcher_list(page: dict[str, Any]) -> list[tuple[str, int]]:
    return [(w["username"], w["connections"]) for w in page["watcherList"]]


def until(condition: Callable[[], bool], within: float) -> float:
    start = time.monotonic()
    while not condition():
        assert time.monotonic() - start < within, "not in time"
        time.sleep(0.1)
    return time.monotonic() - start


def access_counts(ws: ClientConnection, seconds: float) -> list[int]:
    """The watcher counts of the access messages ``ws`` gets within ``seconds``."""
    counts = []
    deadline = time.monotonic() + seconds
    while (left := deadline - time.monotonic()) > 0:
        try:
            frames = _frames(ws, left)
        except TimeoutError:
            break
        counts += [m["access"]["watchers"] for m in frames if m["type"] == "access"]
    return counts


def test_a_watcher_on_the_follower_counts_on_the_owners_page_until_it_leaves(
    workers: dict[str, Any],
) -> None:
    owner, follower, cookies = workers["owner"], workers["follower"], workers["cookies"]
    with watching(owner, cookies["tina"]) as teacher:
        until(lambda: rig_page(owner, cookies["tina"])["access"]["watchers"] == 1, within=5)
        access_counts(teacher, 0.5)  # what tina's own arrival sent
        with watching(follower, cookies["ana"]):
            # The owner hears of ana within its read of the others (1 s) and their write.
            waited = until(
                lambda: watcher_list(rig_page(owner, cookies["tina"])) == [("ana", 1), ("tina", 1)],
                within=3,
            )
            assert waited < 2.5
            page = rig_page(owner, cookies["tina"])
            assert page["access"]["watchers"] == 2
            assert 2 in access_counts(teacher, 1.0)  # and tina's live page was told
            # Ana opens the rig on the owner too: one person, two connections.
            with watching(owner, cookies["ana"]):
                until(lambda: ("ana", 2) in watcher_list(rig_page(owner, cookies["tina"])), 3)
                assert rig_page(owner, cookies["tina"])["access"]["watchers"] == 2
            # A student sees the count, not the list.
            assert rig_page(follower, cookies["bo"])["access"]["watchers"] == 3
            assert rig_page(owner, cookies["bo"])["watcherList"] is None
        closed = time.monotonic()
        # Closed: bo's page (a request, on the owner) counts for a timeout, ana's socket for
        # a timeout after it closed, as on one server; then they leave the count and list.
        until(lambda: rig_page(owner, cookies["tina"])["access"]["watchers"] == 1, within=8)
        left = time.monotonic() - closed
        assert TIMEOUT - 0.5 < left < TIMEOUT + 3
        assert watcher_list(rig_page(owner, cookies["tina"])) == [("tina", 1)]
        assert access_counts(teacher, 2.0)[-1:] == [1]
