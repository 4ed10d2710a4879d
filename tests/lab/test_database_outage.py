"""The database goes away: 503 ``database_unavailable`` with Retry-After, logged once.

A real PostgreSQL stops taking this lab's connections (``ALLOW_CONNECTIONS
false`` on the test run's database, and the lab's own sessions terminated, as
a restart or a failover would), then takes them again. While it is away every
request gets the documented answer in the reader's language, never a 500;
the outage is logged once, not per request; afterwards the lab answers again
and nothing recorded before is lost.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url

from thermolab.lab.clock import ManualClock
from thermolab.lab.db import Database
from thermolab.lab.http.app import create_app
from thermolab.lab.http.outage import RETRY_AFTER
from thermolab.lab.runs import RunRequest
from thermolab.lab.runs.export import RunExport
from thermolab.lab.service import Lab
from thermolab.rigs import TwinRig

from .conftest import FAST_HASHER, PASSWORD, empty_postgres, make_config
from .test_runs import StepClock, person, until

pytestmark = pytest.mark.postgres

APP_NAME = "thermolab-outage-test"


@pytest.fixture
def rig_clock() -> Iterator[StepClock]:
    clock = StepClock()
    yield clock
    clock.allow(math.inf)  # never leave a run blocked behind a test


@pytest.fixture
def lab_on_postgres(migrated_postgres: str, tmp_path: Path, rig_clock: StepClock) -> Iterator[Lab]:
    """A lab whose connections say who they are, so that only they are cut; its twins'
    time passes only as far as the test allows."""
    url = make_url(migrated_postgres).update_query_dict({"application_name": APP_NAME})
    empty_postgres(migrated_postgres)  # an empty lab (the schema is shared by the run)
    rendered = url.render_as_string(hide_password=False)
    lab = Lab(
        make_config(tmp_path, rendered),
        clock=ManualClock(),
        hasher=FAST_HASHER,
        opener=lambda rig: TwinRig("paper", clock=rig_clock),
        database=Database(rendered, pool_size=2, max_overflow=2),
    )
    lab.start()
    yield lab
    lab.close()


class Outage:
    """Cut the lab's database off, and bring it back (always, at the end)."""

    def __init__(self, server_url: str) -> None:
        url = make_url(server_url)
        self.database = url.database
        self.admin = create_engine(url.set(database="postgres"), isolation_level="AUTOCOMMIT")

    def begin(self) -> None:
        with self.admin.connect() as c:
            c.execute(text(f'ALTER DATABASE "{self.database}" ALLOW_CONNECTIONS false'))
            c.execute(
                text(
                    "SELECT pg_terminate_backend(pid) FROM pg_stat_activity "
                    "WHERE datname = :db AND application_name = :app"
                ),
                {"db": self.database, "app": APP_NAME},
            )

    def end(self) -> None:
        with self.admin.connect() as c:
            c.execute(text(f'ALTER DATABASE "{self.database}" ALLOW_CONNECTIONS true'))
        self.admin.dispose()


def test_requests_get_503_with_retry_after_while_the_database_is_away(
    lab_on_postgres: Lab, postgres_server: str, caplog: pytest.LogCaptureFixture
) -> None:
    lab = lab_on_postgres
    lab.users.add("ana", PASSWORD, "student")
    outage = Outage(lab.config.database)
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        assert client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        before = client.get("/api/session")
        assert before.status_code == 200, before.text
        try:
            outage.begin()
            with caplog.at_level(logging.WARNING, logger="thermolab.lab.http.outage"):
                answers = [
                    client.get("/api/session"),
                    client.get("/api/runs"),
                    client.get("/api/session", headers={"Accept-Language": "pt-BR"}),
                ]
            for answer in answers:
                assert answer.status_code == 503, answer.text
                assert answer.headers["Retry-After"] == str(RETRY_AFTER)
                assert answer.json()["code"] == "database_unavailable"
            assert answers[0].json()["message"].startswith("The lab cannot reach its database")
            assert answers[2].json()["message"].startswith("O laboratório não consegue")
            logged = [r for r in caplog.records if "does not answer" in r.getMessage()]
            assert len(logged) == 1, [r.getMessage() for r in caplog.records]
            assert "accepting connections" in logged[0].getMessage() or "terminat" in (
                logged[0].getMessage()
            )
        finally:
            outage.end()
        # Back: the pool reconnects, and what was recorded before is all there.
        after = client.get("/api/session")
        assert after.status_code == 200, after.text
        assert after.json()["username"] == before.json()["username"] == "ana"


def test_a_run_rides_out_the_database_going_away_and_keeps_every_sample(
    lab_on_postgres: Lab, rig_clock: StepClock
) -> None:
    lab = lab_on_postgres
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, RunRequest(dt=1.0, samples=300, signal="step:0:10@5"))
    rig_clock.allow(99)
    until(lambda: lab.runs.get(run.id, ana).samples_stored >= 100)
    outage = Outage(lab.config.database)
    try:
        outage.begin()
        rig_clock.allow(199)  # 100 samples taken while nothing can be stored
        time.sleep(1.5)  # the writer tries and fails about three times (every 0.5 s)
    finally:
        outage.end()
    # The run went on through the outage, and what it took is being stored now.
    until(lambda: lab.runs.get(run.id, ana).samples_stored >= 200)
    going = lab.runs.get(run.id, ana)
    assert (going.status, going.samples_taken) == ("running", 200)
    rig_clock.allow(math.inf)
    lab.runs.wait("twin", timeout=60)
    done = lab.runs.get(run.id, ana)
    assert (done.status, done.samples_stored) == ("finished", 300)
    ks = [k for k, *_ in RunExport(lab.db).samples(run.id)]
    assert ks == list(range(300)), "a sample is missing, doubled or out of order"
