"""``/healthz``, ``/readyz`` and ``/metrics``, read during a run with a watcher connected."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from thermolab.lab.http import observe
from thermolab.lab.http.app import create_app
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.http.observe import METRICS_TOKEN_VARIABLE
from thermolab.lab.service import Lab

from .conftest import LabFactory
from .test_runs import StepClock, lab_request, person, stored_samples, twin_lab, until


@pytest.fixture
def step_clock() -> Iterator[StepClock]:
    clock = StepClock()
    yield clock
    clock.allow(math.inf)  # never leave a run blocked behind a test


def scrape(
    client: TestClient, **headers: str
) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """``/metrics`` read by prometheus_client's own parser: (name, labels) -> value."""
    response = client.get("/metrics", headers=headers)
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/plain; version=")
    return {
        (sample.name, tuple(sorted(sample.labels.items()))): sample.value
        for family in text_string_to_metric_families(response.text)
        for sample in family.samples
    }


def login(lab: Lab, name: str) -> dict[str, str]:
    token, _ = lab.sessions.create(lab.users.get(name))
    return {"cookie": f"{COOKIE_NAME}={token}"}


def test_metrics_and_readiness_answer_during_a_run(
    make_lab: LabFactory, step_clock: StepClock
) -> None:
    lab = twin_lab(make_lab, step_clock)
    ana, ben = person(lab, "ana"), person(lab, "ben")
    lab.access.request_control("twin", ana)
    lab.access.request_control("twin", ben)
    run = lab.runs.start("twin", ana, lab_request(samples=100))
    step_clock.allow(9.0)
    until(lambda: stored_samples(lab, run.id) == 10)
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with TestClient(app, client=("127.0.0.1", 40000)) as client:
        assert client.get("/healthz").json() == {"status": "alive"}
        ready = client.get("/readyz")
        assert ready.status_code == 200
        assert ready.json()["checks"]["rigs"] == {"twin": "in_service", "other": "in_service"}
        assert ready.json()["checks"]["database"]["ok"] is True
        ana_login = login(lab, "ana")
        assert client.get(f"/api/runs/{run.id}", headers=ana_login).status_code == 200
        assert client.get("/api/runs/999999", headers=ana_login).status_code == 404
        with client.websocket_connect("/api/rigs/twin/live", headers=ana_login) as ws:
            assert ws.receive_json()["type"] == "hello"
            figures = scrape(client)
        after = scrape(client)
    step_clock.allow(math.inf)
    lab.runs.wait("twin", timeout=30)

    def value(name: str, **labels: str) -> float:
        return figures[(name, tuple(sorted(labels.items())))]

    route = "/api/runs/{run_id}"
    assert value("thermolab_http_requests_total", method="GET", route=route, status="200") == 1
    assert value("thermolab_http_requests_total", method="GET", route=route, status="404") == 1
    assert value("thermolab_http_request_duration_seconds_count", method="GET", route=route) == 2
    assert value("thermolab_http_requests_total", method="GET", route="/readyz", status="200") == 1
    assert value("thermolab_live_sockets", rig="twin") == 1
    assert value("thermolab_live_sockets", rig="other") == 0
    assert value("thermolab_watchers", rig="twin") == 2  # ana and ben, who asked for it
    assert value("thermolab_queue_waiting", rig="twin") == 1
    assert value("thermolab_rig_controlled", rig="twin") == 1
    assert value("thermolab_runs_total", rig="twin", status="running") == 1
    assert value("thermolab_rig_in_service", rig="twin") == 1
    assert value("thermolab_rig_fault", rig="twin") == 0
    assert value("thermolab_database_up") == 1
    assert 0 < value("thermolab_database_round_trip_seconds") < 5
    assert value("process_resident_memory_bytes") > 0
    assert after[("thermolab_live_sockets", (("rig", "twin"),))] == 0


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_metrics_are_for_loopback_or_the_token(lab: Lab, monkeypatch: pytest.MonkeyPatch) -> None:
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with TestClient(app) as remote:  # the test client's address is not loopback
        assert remote.get("/metrics").status_code == 403
        assert remote.get("/metrics", headers={"authorization": "Bearer guess"}).status_code == 403
        assert remote.get("/healthz").status_code == 200
        assert remote.get("/readyz").status_code == 200
    monkeypatch.setenv(METRICS_TOKEN_VARIABLE, "s3cret")
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with TestClient(app) as remote:
        assert any(
            key[0] == "thermolab_info" for key in scrape(remote, authorization="Bearer s3cret")
        )
        assert remote.get("/metrics", headers={"authorization": "Bearer s3cre"}).status_code == 403


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_readiness_fails_when_the_database_does_not_answer(
    lab: Lab, monkeypatch: pytest.MonkeyPatch
) -> None:
    app = create_app(lab.config, lab=lab, sweep_interval=None)

    def unreachable(lab: Lab) -> float:
        raise OSError("no database")

    monkeypatch.setattr(observe, "_database_round_trip", unreachable)
    with TestClient(app) as client:
        answer = client.get("/readyz")
    assert answer.status_code == 503
    assert answer.json()["checks"]["database"] == {"ok": False, "error": "OSError"}
