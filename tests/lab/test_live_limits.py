"""Live socket limits: sockets per rig, replay paged from the store and capped, budget per user."""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import math
from collections.abc import Coroutine, Iterator
from dataclasses import replace
from typing import Any, TypeVar

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from thermolab.lab.config import RigConfig
from thermolab.lab.http.app import create_app
from thermolab.lab.http.live_replay import PAGE, ReplayBudget
from thermolab.lab.http.live_socket import LiveEndpoint
from thermolab.lab.runs.export import RunExport
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory
from .test_live import login, receive
from .test_runs import StepClock, until

T = TypeVar("T")


def run_alone(scenario: Coroutine[Any, Any, T]) -> T:
    """``asyncio.run`` in a thread of its own: a browser test's Playwright, run earlier
    by the same pytest-xdist worker, keeps an event loop in the main thread."""
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, scenario).result()


@pytest.fixture
def step_clock() -> Iterator[StepClock]:
    clock = StepClock()
    yield clock
    clock.allow(math.inf)


def make(make_lab: LabFactory, clock: Any = None, **access: Any) -> tuple[Lab, TestClient]:
    """A lab whose access policy has ``access`` (the socket limits), and a client of its app."""

    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=clock if rig.id == "twin" and clock else VirtualClock())

    lab = make_lab(opener=opener)
    lab.config = replace(lab.config, access=replace(lab.config.access, **access))
    for name in ("ana", "ben", "tina"):
        lab.users.add(name, PASSWORD, "student")
    return lab, TestClient(create_app(lab.config, lab=lab, sweep_interval=None))


def test_a_rig_holds_at_most_its_configured_sockets(make_lab: LabFactory) -> None:
    lab, client = make(make_lab, live_sockets_per_rig=2)
    with client, contextlib.ExitStack() as stack:
        for name in ("ana", "ben"):
            ws = stack.enter_context(
                client.websocket_connect("/api/rigs/twin/live", headers=login(lab, name))
            )
            assert receive(ws)["type"] == "hello"
        tina = login(lab, "tina")
        with (
            client.websocket_connect("/api/rigs/twin/live", headers=tina) as ws,
            pytest.raises(WebSocketDisconnect) as info,
        ):
            ws.receive_json()
        assert info.value.code == 4503
        assert info.value.reason == "rig 'twin' has its 2 live sockets; try again later"
        # Another rig has sockets of its own.
        with client.websocket_connect("/api/rigs/other/live", headers=tina) as ws:
            assert receive(ws)["type"] == "hello"
        stack.close()  # ana and ben leave: their places are free again
        with client.websocket_connect("/api/rigs/twin/live", headers=tina) as ws:
            assert receive(ws)["type"] == "hello"


def held_run(lab: Lab, client: TestClient, clock: StepClock, stored: int) -> tuple[int, int]:
    """A run on ``twin`` held after ``stored`` samples; returns its id and a ``since`` before it."""
    ana = login(lab, "ana")
    client.post("/api/rigs/twin/control", headers=ana)
    with client.websocket_connect("/api/rigs/twin/live", headers=ana) as ws:
        since: int = ws.receive_json()["seq"]
    run_id: int = client.post(
        "/api/rigs/twin/runs",
        headers=ana,
        json={"dt": 1, "samples": stored + 100, "methods": ["lsm"]},
    ).json()["id"]
    clock.allow(stored - 0.5)
    until(lambda: lab.runs.record(run_id).samples_stored == stored)
    return run_id, since


def frames_until_live(ws: Any) -> list[Any]:
    """The frames of a replay, up to the first that is not from the store."""
    frames = []
    while True:
        frame = ws.receive_json()
        if isinstance(frame, dict) and frame["type"] in ("samples", "truncated"):
            if frame["type"] == "samples" and "seq" in frame:
                return frames  # from memory: the store's part is over
            frames.append(frame)
        elif frames:
            return frames


def test_a_long_replay_is_paged_and_capped_to_the_first_and_newest_samples(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab, client = make(make_lab, step_clock, live_replay_samples=2200)
    live: LiveEndpoint = client.app.state.live  # type: ignore[attr-defined]
    live.hub.channels["twin"]._ring = type(live.hub.channels["twin"]._ring)(maxlen=5)
    with client:
        run_id, since = held_run(lab, client, step_clock, 2500)
        url = f"/api/rigs/twin/live?since={since}"
        with client.websocket_connect(url, headers=login(lab, "ben")) as ws:
            assert ws.receive_json()["type"] == "hello"
            first, notice, *pages = frames_until_live(ws)
        # The run's first sample, where the rest skips to, then the newest samples in pages.
        assert [item["k"] for item in first["items"]] == [0]
        assert notice == {"type": "truncated", "run": run_id, "from": 301, "limit": 2200}
        assert [len(page["items"]) for page in pages] == [PAGE, PAGE, 199]
        ks = [item["k"] for page in pages for item in page["items"]]
        assert ks == list(range(301, 2500))
        assert {item["run"] for page in pages for item in page["items"]} == {run_id}
        # Under the cap, the whole run comes, paged, with no notice.
        live._replay_limit = 2500
        with client.websocket_connect(url, headers=login(lab, "ben")) as ws:
            ws.receive_json()
            pages = frames_until_live(ws)
        assert [len(page["items"]) for page in pages] == [PAGE, PAGE, 500]
        assert [item["k"] for page in pages for item in page["items"]] == list(range(2500))
        step_clock.allow(math.inf)
        lab.runs.wait("twin", timeout=30)


def test_the_store_reads_a_run_in_keyset_pages(make_lab: LabFactory, step_clock: StepClock) -> None:
    lab, client = make(make_lab, step_clock)
    with client:
        run_id, _ = held_run(lab, client, step_clock, 30)
        store: RunExport = lab.runs.stored_samples
        page = store.sample_page(run_id, None, 10)
        assert [k for k, *_ in page] == list(range(10))
        assert [k for k, *_ in store.sample_page(run_id, 9, 10, upto=14)] == list(range(10, 15))
        assert store.sample_page(run_id, 29, 10) == []
        assert store.newest_samples(run_id, 5) == (25, 29)
        assert store.newest_samples(run_id, 500) == (0, 29)  # fewer than asked: all
        assert store.newest_samples(run_id + 1, 5) is None
        step_clock.allow(math.inf)
        lab.runs.wait("twin", timeout=30)


def test_one_replay_at_a_time_per_user_and_others_in_parallel() -> None:
    async def scenario() -> list[str]:
        budget = ReplayBudget(concurrent=2)
        order: list[str] = []
        release = asyncio.Event()

        async def replay(user: int, name: str) -> None:
            async with budget.turn(user):
                order.append(f"{name} starts")
                await release.wait()
                order.append(f"{name} ends")

        tasks = [
            asyncio.ensure_future(replay(1, "mallory 1")),
            asyncio.ensure_future(replay(1, "mallory 2")),
            asyncio.ensure_future(replay(2, "olga")),
        ]
        await asyncio.sleep(0.01)
        # Olga does not wait for mallory; mallory's second replay waits for her first.
        assert order == ["mallory 1 starts", "olga starts"]
        release.set()
        await asyncio.gather(*tasks)
        assert budget._turns == {}  # nothing kept for users with no replay
        return order

    order = run_alone(scenario())
    assert order.index("mallory 2 starts") > order.index("mallory 1 ends")


def test_replays_of_every_user_together_keep_to_the_servers_rate() -> None:
    async def scenario() -> float:
        budget = ReplayBudget(rate=1e9, server_rate=10_000)
        loop = asyncio.get_running_loop()
        start = loop.time()

        async def one_user() -> None:  # two pages of 1000 samples, each user unpaced alone
            for sent in (1000, 2000):
                await budget.pace(start, sent, 1000)

        await asyncio.gather(*(one_user() for _ in range(3)))
        return loop.time() - start

    # 6000 samples at 10 000 a second: never sooner than 0.6 s (whatever the users).
    assert run_alone(scenario()) >= 0.6 - 1e-3
