"""A storm of joins (issue #26): joiners go through a few per turn of the event loop,
and a join whose login was just seen costs no store round trip.

What a storm costs the watchers in time is ``benchmarks/bench_join_storm.py``'s;
these tests check the behaviour that keeps it low: the order in which the loop
runs joiners and what became ready meanwhile (a sample's flush), and which
joins read the store.
"""

from __future__ import annotations

import asyncio
import json
import socket
import threading
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import pytest
import uvicorn
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect
from websockets.sync.client import connect

from thermolab.cli.http_server import _bounded_h11, _framed_websockets
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.db.models import Role
from thermolab.lab.http.app import create_app
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.http.live_logins import KnownLogins
from thermolab.lab.live.turnstile import Turnstile, loop_turnstile
from thermolab.lab.service import Lab

from .conftest import PASSWORD, LabFactory
from .test_live import login, receive
from .test_live_limits import run_alone
from .test_runs import until

# The order of joiners and what reads the store: the same Python on either database.
pytestmark = pytest.mark.sqlite_only

# -- the turnstile ---------------------------------------------------------------------------


def test_a_turnstile_lets_a_few_through_per_turn_in_the_order_they_came() -> None:
    async def scenario() -> list[list[int]]:
        gate = Turnstile(per_turn=3)
        through: list[int] = []
        turns: list[list[int]] = []

        async def joiner(n: int) -> None:
            await gate.turn()
            through.append(n)

        tasks = [asyncio.ensure_future(joiner(n)) for n in range(8)]
        while not all(task.done() for task in tasks):
            await asyncio.sleep(0)
            turns.append(list(through))
            through.clear()
        return [turn for turn in turns if turn]

    assert run_alone(scenario()) == [[0, 1, 2], [3, 4, 5], [6, 7]]


def test_what_becomes_ready_while_joiners_wait_runs_before_the_next_of_them() -> None:
    # A sample's flush is scheduled from the sampling thread while a storm's joiners
    # wait: it must not wait behind all of them, only behind those already let through.
    async def scenario() -> list[str]:
        gate = Turnstile(per_turn=2)
        order: list[str] = []
        loop = asyncio.get_running_loop()

        async def joiner(n: int) -> None:
            await gate.turn()
            order.append(f"joiner {n}")
            if n == 0:  # while the first is served, a sample comes in
                threading.Thread(
                    target=loop.call_soon_threadsafe, args=(order.append, "flush")
                ).start()
                await asyncio.sleep(0.05)  # the thread has scheduled it by then

        await asyncio.gather(*(joiner(n) for n in range(6)))
        return order

    order = run_alone(scenario())
    assert order.index("flush") <= 4  # not behind the 6 joiners: at most one turn more
    assert [o for o in order if o != "flush"] == [f"joiner {n}" for n in range(6)]


def test_a_joiner_that_leaves_while_it_waits_takes_no_place() -> None:
    async def scenario() -> tuple[list[int], int]:
        gate = Turnstile(per_turn=1)
        through: list[int] = []

        async def joiner(n: int) -> None:
            await gate.turn()
            through.append(n)

        tasks = [asyncio.ensure_future(joiner(n)) for n in range(4)]
        await asyncio.sleep(0)  # the first goes through; the others wait
        tasks[1].cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        return through, gate.waiting

    assert run_alone(scenario()) == ([0, 2, 3], 0)


def test_a_turnstile_lets_someone_through() -> None:
    with pytest.raises(ValueError, match="at least one"):
        Turnstile(per_turn=0)


# -- logins known to the live stream -----------------------------------------------------------


def make(make_lab: LabFactory) -> tuple[Lab, TestClient]:
    lab = make_lab()
    for name in ("ana", "ben"):
        lab.users.add(name, PASSWORD, "student")
    return lab, TestClient(create_app(lab.config, lab=lab, sweep_interval=None))


def counted_reads(lab: Lab, monkeypatch: pytest.MonkeyPatch) -> list[str | None]:
    """The cookie tokens the store is asked about, in order."""
    asked: list[str | None] = []
    resolve = lab.sessions.resolve

    def counted(token: str | None) -> Principal | None:
        asked.append(token)
        return resolve(token)

    monkeypatch.setattr(lab.sessions, "resolve", counted)
    return asked


def join(client: TestClient, token: str) -> dict[str, Any]:
    """Open a socket with the login ``token``; return its first message."""
    cookie = {"cookie": f"{COOKIE_NAME}={token}"}
    with client.websocket_connect("/api/rigs/twin/live", headers=cookie) as ws:
        return receive(ws)


def test_a_join_whose_login_was_just_seen_reads_nothing_from_the_store(
    make_lab: LabFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    lab, client = make(make_lab)
    asked = counted_reads(lab, monkeypatch)
    ana, _ = lab.sessions.create(lab.users.get("ana"))
    ben, _ = lab.sessions.create(lab.users.get("ben"))
    with client:
        for _ in range(5):  # a student's tabs, a page reloaded: the first join reads
            assert join(client, ana)["type"] == "hello"
        assert asked == [ana]
        assert join(client, ben)["type"] == "hello"  # another login is read on its own
        assert asked == [ana, ben]


def test_a_login_that_ends_is_read_again_and_refused(
    make_lab: LabFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    lab, client = make(make_lab)
    asked = counted_reads(lab, monkeypatch)
    ana, _ = lab.sessions.create(lab.users.get("ana"))
    with client:
        assert join(client, ana)["type"] == "hello"
        lab.sessions.end(ana)  # logged out: the lab says so at once
        with pytest.raises(WebSocketDisconnect) as refused:
            join(client, ana)
        assert refused.value.code == 4401
        assert asked == [ana, ana]


def test_a_login_is_read_again_once_the_labs_time_has_moved_on(
    make_lab: LabFactory, monkeypatch: pytest.MonkeyPatch, clock: ManualClock
) -> None:
    # An idle login ends in the lab's time: one seen a while ago (as the lab counts) is
    # read again, and refused if its time ran out meanwhile.
    lab, client = make(make_lab)
    asked = counted_reads(lab, monkeypatch)
    ana, _ = lab.sessions.create(lab.users.get("ana"))
    with client:
        assert join(client, ana)["type"] == "hello"
        clock.advance(60.0)
        assert join(client, ana)["type"] == "hello"
        assert asked == [ana, ana]
        clock.advance(lab.config.access.session_lifetime)
        with pytest.raises(WebSocketDisconnect) as refused:
            join(client, ana)
        assert refused.value.code == 4401


def known_logins(lab: Lab, ttl: float = 5.0) -> tuple[KnownLogins, list[str], asyncio.Event]:
    """Logins known for ``ttl`` s, read by a stand-in for the store that waits for its event."""
    reads: list[str] = []
    release = asyncio.Event()

    async def in_thread(work: Callable[[], Principal | None]) -> Principal | None:
        reads.append("read")
        await release.wait()
        return work()

    return KnownLogins(lab, ttl, in_thread), reads, release


def test_sockets_joining_at_once_with_one_login_read_it_once(make_lab: LabFactory) -> None:
    lab, _ = make(make_lab)
    ana, _ = lab.sessions.create(lab.users.get("ana"))

    async def scenario() -> tuple[list[str], list[Principal | None], int]:
        known, reads, release = known_logins(lab)
        joins = [asyncio.ensure_future(known.resolve(ana, None)) for _ in range(50)]
        await asyncio.sleep(0.01)
        joins[0].cancel()  # one page closed meanwhile: the others' read goes on
        release.set()
        who = await asyncio.gather(*joins[1:])
        return reads, who, known.reads

    reads, who, counted = run_alone(scenario())
    assert reads == ["read"]
    assert counted == 1
    assert {(w.username, w.role) for w in who if w is not None} == {("ana", Role.STUDENT)}
    assert len(who) == 49
    assert None not in who


def test_a_login_refused_or_ended_while_it_is_read_is_not_remembered(
    make_lab: LabFactory,
) -> None:
    lab, _ = make(make_lab)
    ana, who = lab.sessions.create(lab.users.get("ana"))

    async def scenario() -> tuple[Principal | None, Principal | None, int]:
        known, _, release = known_logins(lab)
        release.set()
        nobody = await known.resolve("not-a-session", None)
        await known.resolve("not-a-session", None)  # a refusal is read again
        assert known.reads == 2
        release.clear()
        reading = asyncio.ensure_future(known.resolve(ana, None))
        await asyncio.sleep(0.01)
        known.forget(sessions={who.session_id})  # ended while it was read
        release.set()
        first = await reading
        await known.resolve(ana, None)  # read again: what was read may be stale
        return nobody, first, known.reads

    nobody, first, reads = run_alone(scenario())
    assert nobody is None
    assert first is not None
    assert reads == 4


def test_no_credentials_read_nothing_and_a_zero_ttl_remembers_nothing(
    make_lab: LabFactory,
) -> None:
    lab, _ = make(make_lab)
    ana, _ = lab.sessions.create(lab.users.get("ana"))

    async def scenario() -> tuple[Principal | None, int]:
        known, _, release = known_logins(lab, ttl=0.0)
        release.set()
        nobody = await known.resolve(None, None)
        for _ in range(3):
            await known.resolve(ana, None)
        return nobody, known.reads

    assert run_alone(scenario()) == (None, 3)


# -- thermolab serve's protocols: upgrades wait for their turn -----------------------------------


@pytest.fixture
def served_one_per_turn(make_lab: LabFactory) -> Iterator[tuple[Lab, str, list[int]]]:
    """``thermolab serve``'s HTTP and WebSocket protocols, one joiner step per loop turn."""
    lab = make_lab()
    lab.users.add("ana", PASSWORD, "student")  # her page in a dozen tabs
    lab.config = replace(lab.config, access=replace(lab.config.access, live_sockets_per_login=12))
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    config = uvicorn.Config(
        app,
        host="127.0.0.1",
        port=port,
        log_level="warning",
        ws_per_message_deflate=False,
        http=_bounded_h11(10.0),
        ws=_framed_websockets(),
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deferred: list[int] = []
    try:
        until(lambda: server.started)
        loop = app.state.live.hub.loop

        def one_per_turn() -> None:
            turnstile = loop_turnstile()
            turnstile.per_turn = 1
            place = turnstile.place

            def counted() -> asyncio.Future[None] | None:
                future = place()
                if future is not None:
                    deferred.append(1)
                return future

            turnstile.place = counted  # type: ignore[method-assign]

        loop.call_soon_threadsafe(one_per_turn)
        yield lab, f"ws://127.0.0.1:{port}/api/rigs/twin/live", deferred
    finally:
        server.should_exit = True
        thread.join(timeout=30)


def test_upgrades_beyond_a_turns_places_wait_for_later_turns_and_all_get_in(
    served_one_per_turn: tuple[Lab, str, list[int]],
) -> None:
    lab, url, deferred = served_one_per_turn
    cookie = login(lab, "ana")
    first: list[str] = []
    lock = threading.Lock()

    def join() -> None:
        with connect(url, additional_headers=cookie, open_timeout=30) as ws:
            message = json.loads(ws.recv(timeout=30))
            with lock:
                first.append(message["type"])

    joiners = [threading.Thread(target=join) for _ in range(12)]
    for joiner in joiners:
        joiner.start()
    for joiner in joiners:
        joiner.join(timeout=60)
    assert first == ["hello"] * 12
    assert deferred  # some waited for a later turn (upgrade, ASGI call, login, hello)
