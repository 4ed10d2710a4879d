"""The login throttle and the live-socket limits hold across real web workers (issue #14).

Two ``thermolab serve --broker redis://...`` processes on one PostgreSQL
schema (:mod:`thermolab.lab.fleet.workers`), real HTTP and WebSockets: failed
logins on one worker delay the next on the other, and LTI login initiations
count on both; a rig limited to 3 live sockets refuses a 4th on the other
worker with 4503 and a login limited to 2 a 3rd with 4429; a killed worker's
sockets stop counting once its published counts expire. Skipped, with the
reason, where PostgreSQL or Redis is absent.
"""

from __future__ import annotations

import contextlib
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from .fleet_setup import PASSWORD, seed_lab, stop
from .test_workers import Worker, _frames, _start

pytestmark = [pytest.mark.postgres, pytest.mark.redis, pytest.mark.slow]

LIMITS_TOML = """
[access]
login_failures_per_user = 2
login_attempts_per_address = 1000
live_sockets_per_login = 2
live_sockets_per_rig = 3

[rig_defaults]
idle_limit = 0

[[rigs]]
id = "twin"
title = "Twin"
spec = "sim:paper-practical"
"""

STUDENTS = ("ana", "bo", "cy", "di", "ed")


COOKIES: dict[str, str] = {}  # each student's session cookie, for this test's lab


@pytest.fixture
def workers(tmp_path: Path, postgres_url: str, redis_url: str) -> Iterator[dict[str, Worker]]:
    people = [(name, "student") for name in STUDENTS]
    COOKIES.update(seed_lab(tmp_path, postgres_url, LIMITS_TOML, people))
    started = [_start(tmp_path, postgres_url, redis_url)]
    try:
        started.append(_start(tmp_path, postgres_url, redis_url))
        yield {"owner": started[0], "follower": started[1]}
    finally:
        stop([worker.process for worker in started])
        COOKIES.clear()


@contextlib.contextmanager
def watching(worker: Worker, name: str) -> Iterator[ClientConnection]:
    """A live socket of ``name`` on ``worker``'s ``twin``, past its hello."""
    headers = {"Cookie": COOKIES[name]}
    with connect(worker.ws + "/api/rigs/twin/live", additional_headers=headers) as ws:
        assert _frames(ws, 10)[0]["type"] == "hello"
        yield ws


def refusal(worker: Worker, name: str) -> int | None:
    """The close code a new socket of ``name`` on ``worker`` gets (``None``: accepted)."""
    try:
        with watching(worker, name):
            return None
    except ConnectionClosed as closed:
        return None if closed.rcvd is None else closed.rcvd.code


def until_accepted(worker: Worker, name: str, within: float) -> float:
    """Seconds until a socket of ``name`` on ``worker`` is accepted (fails after ``within``)."""
    start = time.monotonic()
    while refusal(worker, name) is not None:
        assert time.monotonic() - start < within, "still refused"
        time.sleep(0.25)
    return time.monotonic() - start


def test_failed_logins_and_lti_initiations_on_one_worker_count_on_the_other(
    workers: dict[str, Worker],
) -> None:
    wrong = {"username": "ana", "password": "not the password"}
    for base in (workers["owner"].base, workers["follower"].base, workers["owner"].base):
        assert httpx.post(base + "/api/session", json=wrong, timeout=30).status_code == 401
    delayed = httpx.post(workers["follower"].base + "/api/session", json=wrong, timeout=30)
    assert delayed.status_code == 429
    assert delayed.headers["retry-after"] == "1"
    time.sleep(1.1)
    right = {"username": "ana", "password": PASSWORD}
    assert httpx.post(workers["follower"].base + "/api/session", json=right).status_code == 200
    # LTI login initiations: 30 a minute per address, on both workers together (each
    # refused for its unknown platform, after it was counted).
    bases = (workers["owner"].base, workers["follower"].base)
    for i in range(30):
        assert httpx.get(bases[i % 2] + "/api/lti/login", timeout=30).status_code == 400
    for base in bases:
        assert httpx.get(base + "/api/lti/login", timeout=30).status_code == 429


def test_a_rigs_and_a_logins_sockets_count_on_every_worker_until_a_dead_ones_expire(
    workers: dict[str, Worker],
) -> None:
    owner, follower = workers["owner"], workers["follower"]
    with contextlib.ExitStack() as sockets:
        sockets.enter_context(watching(owner, "ana"))
        sockets.enter_context(watching(follower, "ana"))
        assert refusal(owner, "ana") == 4429  # ana's 2 sockets, one on each worker
        sockets.enter_context(watching(owner, "bo"))
        # The rig's 3 sockets are held (2 on the owner): a 4th is refused on either.
        assert refusal(follower, "cy") == 4503
        assert refusal(owner, "cy") == 4503
    # Closed, they are free again on every worker (published at once, not at the refresh).
    assert until_accepted(follower, "cy", within=1.5) < 1.5
    with contextlib.ExitStack() as sockets:
        for name in ("ana", "bo", "cy"):
            sockets.enter_context(watching(follower, name))
        assert refusal(owner, "di") == 4503
        follower.process.send_signal(signal.SIGKILL)
        follower.process.wait()
        # The dead worker's counts stay until they expire (6 s after its last write).
        assert refusal(owner, "di") == 4503
        waited = until_accepted(owner, "di", within=15)
        assert 2 < waited < 12
