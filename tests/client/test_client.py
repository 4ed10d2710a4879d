"""``thermolab.client`` against a real lab: queue, runs as arrays, revocation, versions (#11)."""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import uvicorn
from fastapi import FastAPI

from thermolab.client import Lab, LabRequestError, RunData
from thermolab.errors import IncompatibleLabError, InvalidParameterError
from thermolab.ident.registry import METHOD_NAMES

from .conftest import ServedLab, free_port


@pytest.mark.slow
def test_a_script_waits_in_the_queue_behind_another_user_and_gets_the_turn(
    served_lab: ServedLab,
) -> None:
    _, ben_token = served_lab.token("ben")
    _, ana_token = served_lab.token("ana")
    with Lab(served_lab.url, ben_token) as ben, Lab(served_lab.url, ana_token) as ana:
        turn = ben.control("kit")
        assert turn.held
        places: list[tuple[int, int]] = []
        got: list[Any] = []

        def wait_for_turn() -> None:
            got.append(
                ana.control(
                    "kit",
                    poll=0.2,
                    on_wait=lambda rig: places.append(
                        (rig["access"]["queuePosition"], rig["access"]["queueSize"])
                    ),
                )
            )

        waiter = threading.Thread(target=wait_for_turn)
        waiter.start()
        deadline = time.monotonic() + 10
        while not places and time.monotonic() < deadline:
            time.sleep(0.05)
        assert places == [(1, 1)]  # told its place while it waits
        assert not got
        turn.set_input(30.0)
        turn.release()
        waiter.join(timeout=10)
        assert got, "the queued script did not get the turn after the release"
        ana_turn = got[0]
        try:
            rig = ana.rig("kit")
            assert rig["access"]["controller"] == "ana"
            # A new controller starts from the safe input, whatever ben left.
            assert ana_turn.read().u == 0.0
            assert ana_turn.set_input(12.5) == 12.5
            assert ana_turn.read().u == 12.5
        finally:
            ana_turn.release()
        assert ben.rig("kit")["access"]["controller"] is None


def test_a_run_is_started_followed_live_and_fetched_as_arrays(served_lab: ServedLab) -> None:
    _, token = served_lab.token("ana")
    with Lab(served_lab.url, token) as lab, lab.control("box") as turn:
        with pytest.raises(InvalidParameterError, match=r"unknown run setting.*windw"):
            turn.start_run(dt=1, samples=50, signal="step:0:5@5", windw=10)
        with pytest.raises(LabRequestError) as refused:
            turn.start_run(dt=1, samples=50, signal="step:0:5@5", methods=["lsm"], gamma=1.5)
        assert refused.value.status == 422
        assert "gamma" in refused.value.detail
        run = turn.start_run(dt=1, samples=60, signal="step:0:5@5", methods=["lsm", "wlsm"])
        messages = list(lab.follow("box", run["id"], timeout=30))
    samples = [m for m in messages if m["type"] == "sample"]
    assert [m["k"] for m in samples] == list(range(60))
    assert messages[-1]["type"] == "run"
    assert messages[-1]["event"] == "ended"
    with Lab(served_lab.url, token) as lab:
        again = list(lab.follow("box", run["id"]))  # over: given from the store, same samples
    assert [(m["k"], m["y"]) for m in again if m["type"] == "sample"] == [
        (m["k"], m["y"]) for m in samples
    ]
    assert again[-1]["event"] == "ended"
    data = lab_data(served_lab, token, run["id"])
    assert len(data) == 60
    np.testing.assert_allclose(data.t, np.arange(60.0), atol=1e-9)
    np.testing.assert_array_equal(data.u, np.where(np.arange(60) >= 5, 5.0, 0.0))
    assert data.y[-1] > data.y[0]  # the box heated
    assert data.units["y"] == "V"
    frame = data.to_pandas()
    assert list(frame.columns[:3]) == ["t", "u", "y"]
    np.testing.assert_array_equal(frame["y"].to_numpy(), data.y)
    assert data.run["status"] == "finished"
    assert data.methods["lsm"]


def test_a_script_identifies_the_kits_heater_2_to_sensor_2(served_lab: ServedLab) -> None:
    _, token = served_lab.token("ana")
    with Lab(served_lab.url, token) as lab, lab.control("dual") as turn:
        with pytest.raises(LabRequestError) as refused:
            turn.start_run(dt=1, samples=20, signal="step:0:50@5", input="q3", output="t2")
        assert (refused.value.status, refused.value.code) == (422, "pair_channel_unknown")
        run = turn.start_run(
            dt=1, samples=20, signal="step:0:50@5", methods=["lsm"], input="q2", output="t2"
        )
        list(lab.follow("dual", run["id"], timeout=60))
    data = lab_data(served_lab, token, run["id"])
    assert (data.run["settings"]["input"], data.run["settings"]["output"]) == ("q2", "t2")
    np.testing.assert_array_equal(data.u, np.zeros(20))  # heater 1 rests; heater 2 steps
    np.testing.assert_array_equal(data.columns["q2"], np.where(np.arange(20) >= 5, 50.0, 0.0))
    assert data.run["status"] == "finished"


def lab_data(served_lab: ServedLab, token: str, run_id: int) -> RunData:
    with Lab(served_lab.url, token) as lab:
        return lab.run_data(run_id)


def test_a_revoked_token_is_refused_at_once_and_its_live_socket_closed(
    served_lab: ServedLab,
) -> None:
    token_id, token = served_lab.token("ana")
    errors: list[BaseException] = []
    lab = Lab(served_lab.url, token)
    try:

        def follow() -> None:
            try:
                list(lab.follow("box", timeout=60))
            except BaseException as exc:
                errors.append(exc)

        follower = threading.Thread(target=follow)
        follower.start()
        with contextlib.closing(served_lab.cookie_client("tina")) as teacher:

            def watchers() -> int:
                rigs = teacher.get("/api/rigs").json()  # the list does not count as watching
                return int(next(r for r in rigs if r["id"] == "box")["access"]["watchers"])

            deadline = time.monotonic() + 10
            while watchers() < 1 and time.monotonic() < deadline:
                time.sleep(0.05)
            assert watchers() >= 1
        with contextlib.closing(served_lab.cookie_client("ana")) as ana:
            revoked_at = time.monotonic()
            assert ana.delete(f"/api/tokens/{token_id}").status_code == 204
        follower.join(timeout=10)
        assert not follower.is_alive()
        assert time.monotonic() - revoked_at < 5
        assert isinstance(errors[0], LabRequestError)
        assert errors[0].status == 4401
        assert "revoked" in errors[0].detail
        with pytest.raises(LabRequestError) as refused:
            lab.rigs()
        assert refused.value.status == 401
        assert "revoked" in str(refused.value)
    finally:
        lab.close()


@pytest.fixture
def other_server() -> Iterator[tuple[str, dict[str, Any]]]:
    """A small HTTP server answering /api/version as the test says (another lab version)."""
    answer: dict[str, Any] = {}
    app = FastAPI()

    @app.get("/api/version")
    def version() -> dict[str, Any]:
        return answer

    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, port=port, log_level="error"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 10
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.02)
    try:
        yield f"http://127.0.0.1:{port}", answer
    finally:
        server.should_exit = True
        thread.join(timeout=10)


@pytest.mark.parametrize(
    ("api", "message"),
    [
        ("2.0", "speaks API 2.0"),
        ("1.9999", None),  # a later minor only adds: compatible
        ("0.9", "speaks API 0.9"),
        ("one", "speaks API one"),
    ],
)
def test_a_lab_of_another_api_version_is_refused_clearly(
    other_server: tuple[str, dict[str, Any]], api: str, message: str | None
) -> None:
    url, answer = other_server
    answer.update({"name": "thermolab", "version": "9.9.9", "api": api})
    if message is None:
        Lab(url, "tlab_x").close()
        return
    with pytest.raises(IncompatibleLabError, match=message) as refused:
        Lab(url, "tlab_x")
    assert "this client speaks 1.0" in str(refused.value)


def test_a_server_that_is_not_a_lab_and_a_lab_that_is_not_there(served_lab: ServedLab) -> None:
    with pytest.raises(IncompatibleLabError, match="not a ThermoLab lab"):
        Lab(served_lab.url + "/nowhere", "tlab_x")
    nowhere = f"http://127.0.0.1:{free_port()}"
    with pytest.raises(LabRequestError, match=f"^cannot reach the lab at {nowhere} ") as gone:
        Lab(nowhere, "tlab_x")
    assert gone.value.code == "unreachable"
    assert gone.value.status is None
    with pytest.raises(InvalidParameterError, match="THERMOLAB_URL"):
        Lab(None, "tlab_x")


def test_the_lab_loads_the_methods_kernels_as_it_starts_not_at_the_first_start(
    served_lab: ServedLab,
) -> None:
    # The first START after a restart would otherwise load them while a script
    # waits (past its 10 s HTTP timeout on a loaded machine). The server says in
    # its log when they are ready; every method is named there.
    log = served_lab.data_dir / "server.log"
    deadline = time.monotonic() + 120
    ready = None
    while ready is None and time.monotonic() < deadline:
        for line in log.read_text(encoding="utf-8", errors="replace").splitlines():
            if line.startswith("{") and "identification methods ready" in line:
                ready = json.loads(line)
                break
        else:
            time.sleep(0.2)
    assert ready is not None, "the lab never said its methods were ready"
    assert ready["logger"] == "thermolab.serve"
    named = ready["message"].split("(", 1)[1].split(")", 1)[0].split(", ")
    assert tuple(named) == METHOD_NAMES
