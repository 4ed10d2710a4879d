"""Remote rigs in a fleet of web workers: ``thermolab agent`` with an owner and a follower.

Real processes: an owner and a follower (``thermolab serve --broker redis://``)
on a fresh PostgreSQL schema, and ``thermolab agent`` driving a twin, given
the follower's address first. The follower closes the agent's link with
``CLOSE_NOT_OWNER`` and the agent dials the owner; a watcher on the follower
sees the remote rig's samples live, with no gap; the hosts page
(``/api/agents``) answers the same from either worker. Skipped, with the
reason, where PostgreSQL or Redis is absent.
"""

from __future__ import annotations

import itertools
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from websockets.sync.client import connect

from .fleet_setup import PEOPLE, seed_lab, start_agent, stop
from .test_workers import Worker, _frames, _start

pytestmark = [pytest.mark.postgres, pytest.mark.redis, pytest.mark.slow]


LAB_TOML = """
[access]
login_attempts_per_address = 1000

[rig_defaults]
control_time_limit = 3600
idle_limit = 0
power_off_grace = 600

[[rigs]]
id = "box"
title = "Box"
spec = "sim:tclab"
agent = true
"""


def _hosts(worker: Worker, cookie: str) -> list[dict[str, Any]]:
    answer = httpx.get(worker.base + "/api/agents", headers={"Cookie": cookie}, timeout=30)
    assert answer.status_code == 200, answer.text
    hosts: list[dict[str, Any]] = answer.json()
    return hosts


@pytest.fixture
def lab_with_agent(
    tmp_path: Path, postgres_url: str, redis_url: str
) -> Iterator[tuple[Worker, Worker, subprocess.Popen[bytes], dict[str, str]]]:
    cookies = seed_lab(tmp_path, postgres_url, LAB_TOML, PEOPLE, agent_rigs=["box"])
    processes: list[subprocess.Popen[bytes]] = []
    try:
        owner = _start(tmp_path, postgres_url, redis_url)
        processes.append(owner.process)
        follower = _start(tmp_path, postgres_url, redis_url)
        processes.append(follower.process)
        # The follower first: it sends the host on to the owner.
        agent = start_agent(tmp_path, [follower.ws, owner.ws])
        processes.append(agent)
        yield owner, follower, agent, cookies
    finally:
        stop(processes)


def test_an_agent_sent_on_by_the_follower_serves_watchers_on_the_follower(
    lab_with_agent: tuple[Worker, Worker, subprocess.Popen[bytes], dict[str, str]],
    tmp_path: Path,
) -> None:
    owner, follower, agent, cookies = lab_with_agent
    tina = cookies["tina"]
    deadline = time.monotonic() + 60
    while True:  # the hosts page, asked of the follower, is the owner's
        (host,) = _hosts(follower, tina)
        if host["online"] and host["fault"] is None:  # linked, and the health check agrees
            break
        assert agent.poll() is None, (tmp_path / "agent.log").read_text()
        assert time.monotonic() < deadline, f"the agent did not link: {host}"
        time.sleep(0.2)
    assert host["rig"] == "box"
    steady = ("rig", "online", "version", "spec", "fault")  # contact times and readings move
    seen = [{k: h[k] for k in steady} for w in (owner, follower) for h in _hosts(w, tina)]
    assert seen[0] == seen[1]
    assert seen[0]["spec"] == "sim:tclab"
    log = (tmp_path / "agent.log").read_text()
    assert "does not own the rigs" in log  # the follower refused it, the owner took it
    assert "linked to " + owner.ws in log
    assert "linked to " + follower.ws not in log

    with connect(
        follower.ws + "/api/rigs/box/live", additional_headers={"Cookie": cookies["bo"]}
    ) as ws:
        assert _frames(ws, 30)[0]["type"] == "hello"
        with httpx.Client(
            base_url=follower.base, headers={"Cookie": cookies["ana"]}, timeout=30
        ) as ana:  # every request through the follower, forwarded to the owner
            assert ana.post("/api/rigs/box/control").status_code == 200
            started = ana.post(
                "/api/rigs/box/runs",
                json={"dt": 0.2, "samples": 300, "signal": "step:0:40@0.4", "methods": ["lsm"]},
            )
            assert started.status_code == 201, started.text
            run_id = started.json()["id"]
        ks: list[int] = []
        seqs: list[int] = []
        while len(ks) < 10:
            for m in _frames(ws, 30):
                items = m["items"] if m["type"] == "samples" else [m]
                for item in items:
                    if m["type"] in ("sample", "samples") and item.get("run") == run_id:
                        ks.append(item["k"])
                if m["type"] in ("sample", "samples"):
                    seqs.append(m["seq"])
    assert ks == list(range(ks[0], ks[0] + len(ks))), ks  # live, in order, no gap
    assert all(b > a for a, b in itertools.pairwise(seqs))
