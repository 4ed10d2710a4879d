"""Exactly one controller under any interleaving: 100 clients ask for one rig at once.

The clients are real threads, released together by a barrier, each with its
own database session and connection, on SQLite and PostgreSQL; the HTTP
variant sends the 100 requests through the app. On PostgreSQL the number of
simultaneous connections is at most 40 (what the server has free); the other
clients queue for a connection and still race for the rig. Four labs share the
database in the first test, as four server processes would.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from datetime import timedelta
from typing import Any, TypeVar

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, func, select, text

from thermolab.lab.accounts.security import hash_token, new_token
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.login_models import LoginSession
from thermolab.lab.db.models import ControlSession, QueueEntry, Role, User
from thermolab.lab.http.app import create_app
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.service import Lab

from .conftest import FAST_HASHER, PASSWORD, LabFactory

CLIENTS = 100
LABS = 4
T = TypeVar("T")


def add_students(lab: Lab, count: int, prefix: str = "student") -> list[tuple[Principal, str]]:
    """Create ``count`` students with a login each, in one transaction; (principal, token)."""
    now = lab.clock.now()
    password_hash = FAST_HASHER.hash(PASSWORD)
    result = []
    with lab.db.write() as session:
        users = [
            User(
                username=f"{prefix}{i:03d}",
                role="student",
                password_hash=password_hash,
                created_at=now,
                password_changed_at=now,
            )
            for i in range(count)
        ]
        session.add_all(users)
        session.flush()
        for user in users:
            token = new_token()
            session.add(
                LoginSession(
                    token_hash=hash_token(token),
                    user_id=user.id,
                    created_at=now,
                    last_seen_at=now,
                    expires_at=now + timedelta(hours=1),
                )
            )
            result.append((Principal(user.id, user.username, Role.STUDENT), token))
    return result


def free_connections(url: str) -> int:
    """Connections the database server can still give this test (with a margin for others)."""
    if not url.startswith("postgresql"):
        return CLIENTS
    engine = create_engine(url)
    with engine.connect() as connection:
        limit = connection.execute(text("SHOW max_connections")).scalar_one()
        used = connection.execute(text("SELECT count(*) FROM pg_stat_activity")).scalar_one()
        reserved = connection.execute(text("SHOW superuser_reserved_connections")).scalar_one()
    engine.dispose()
    return max(4, min(CLIENTS, int(limit) - int(used) - int(reserved) - 10))


def race(calls: list[Callable[[], T]]) -> tuple[list[T], int]:
    """Run the calls in one thread each, all released at once.

    Returns the results in call order and the largest number of calls that
    were in progress at the same moment (evidence that they raced).
    """
    barrier = threading.Barrier(len(calls))
    results: list[Any] = [None] * len(calls)
    spans: list[tuple[float, float]] = [(0.0, 0.0)] * len(calls)

    def run(i: int) -> None:
        barrier.wait()
        start = time.perf_counter()
        try:
            results[i] = calls[i]()
        except BaseException as exc:  # reported below, with the others
            results[i] = exc
        spans[i] = (start, time.perf_counter())

    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(calls))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=120)
    errors = [r for r in results if isinstance(r, BaseException)]
    assert not errors, f"{len(errors)} clients failed, first: {errors[0]!r}"
    events = sorted([(s, 1) for s, _ in spans] + [(e, -1) for _, e in spans])
    in_flight = overlap = 0
    for _, step in events:
        in_flight += step
        overlap = max(overlap, in_flight)
    return results, overlap


def assert_one_controller_and_a_fifo_queue(lab: Lab) -> None:
    with lab.db.read() as session:
        active = session.scalar(
            select(func.count())
            .select_from(ControlSession)
            .where(ControlSession.rig_id == "twin", ControlSession.ended_at.is_(None))
        )
        tickets = list(
            session.scalars(
                select(QueueEntry.ticket).where(
                    QueueEntry.rig_id == "twin", QueueEntry.left_at.is_(None)
                )
            )
        )
    assert active == 1
    assert sorted(tickets) == list(range(2, CLIENTS + 1))
    snap = lab.access.snapshot("twin")
    assert [slot.position for slot in snap.queue] == list(range(1, CLIENTS))
    assert snap.controller is not None
    assert len({slot.user_id for slot in snap.queue} | {snap.controller.user_id}) == CLIENTS


def warm(lab: Lab, connections: int) -> None:
    """Open the pool's connections before the race, so that the race is not about connecting."""
    held = [lab.db.engine.connect() for _ in range(connections)]
    for connection in held:
        connection.close()


def test_hundred_simultaneous_requests_give_one_controller(
    make_lab: LabFactory, database_url: str
) -> None:
    # Four labs on one database stand for four server processes: on SQLite the
    # writers of different processes exclude each other only by BEGIN IMMEDIATE.
    per_lab = max(1, min(40, free_connections(database_url)) // LABS)
    labs = [make_lab(pool_size=per_lab, max_overflow=0) for _ in range(LABS)]
    for lab in labs:
        warm(lab, per_lab)
    people = [who for who, _ in add_students(labs[0], CLIENTS)]

    views, overlap = race(
        [
            lambda who=who, lab=labs[i % LABS]: lab.access.request_control("twin", who)
            for i, who in enumerate(people)
        ]
    )
    roles = [view.access.role for view in views]
    assert roles.count("controller") == 1
    assert roles.count("queued") == CLIENTS - 1
    # Each client was told a different place, and together the places are 1..99.
    queued = [view.access.queue_position for view in views if view.access.role == "queued"]
    assert sorted(p or 0 for p in queued) == list(range(1, CLIENTS))
    assert overlap >= 10
    assert_one_controller_and_a_fifo_queue(labs[0])


def test_hundred_simultaneous_http_requests_give_one_controller(
    make_lab: LabFactory, database_url: str
) -> None:
    connections = min(20, free_connections(database_url))
    lab = make_lab(pool_size=connections, max_overflow=0)
    warm(lab, connections)
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    # Sessions opened directly: 100 logins from one address would be throttled.
    cookies = [f"{COOKIE_NAME}={token}" for _, token in add_students(lab, CLIENTS)]
    # One app, one event loop; the requests come from 100 threads and its
    # routes run in its thread pool, each with a session of its own.
    with TestClient(app) as client:
        responses, overlap = race(
            [
                lambda cookie=cookie: client.post(
                    "/api/rigs/twin/control", headers={"cookie": cookie}
                )
                for cookie in cookies
            ]
        )
    assert {r.status_code for r in responses} == {200}
    access = [r.json()["access"] for r in responses]
    assert [a["role"] for a in access].count("controller") == 1
    assert sorted(a["queuePosition"] for a in access if a["role"] == "queued") == list(
        range(1, CLIENTS)
    )
    assert overlap >= 10
    assert_one_controller_and_a_fifo_queue(lab)


@pytest.mark.parametrize("rounds", [2])
def test_racing_releases_and_requests_keep_one_controller(
    make_lab: LabFactory, database_url: str, rounds: int
) -> None:
    """Controllers releasing while others ask: never two controllers, never a lost place."""
    connections = min(20, free_connections(database_url))
    lab = make_lab(pool_size=connections, max_overflow=0)
    warm(lab, connections)
    people = [who for who, _ in add_students(lab, 20)]
    for _ in range(rounds):
        calls: list[Callable[[], object]] = []
        for who in people:
            calls.append(lambda who=who: lab.access.request_control("twin", who))
            calls.append(lambda who=who: lab.access.release("twin", who))
        race(calls)
        snap = lab.access.snapshot("twin")
        with lab.db.read() as session:
            active = session.scalar(
                select(func.count())
                .select_from(ControlSession)
                .where(ControlSession.ended_at.is_(None))
            )
        assert active == (1 if snap.controller is not None else 0)
        # Somebody waiting while nobody controls would be a lost hand-over.
        assert snap.controller is not None or not snap.queue
        assert [slot.position for slot in snap.queue] == list(range(1, len(snap.queue) + 1))
