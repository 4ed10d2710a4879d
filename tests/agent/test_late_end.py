"""A rig host's end of a run the lab restarted under: its results, stored once.

In-process and quick beside tests/agent/test_restart.py (real processes): the
run row as START stores it, marked interrupted as a restart leaves it, the
host's samples stored by the lab's own store, then the host's ``RunEnded``
as the lab's endpoint hands it on, twice (a resend after a lost Ack).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from datetime import UTC, datetime

import numpy as np
import pytest
from numpy.testing import assert_allclose
from sqlalchemy import func, select

from thermolab.agent.protocol import RunEnded, SampleBatch, SampleOut
from thermolab.lab.config import RigConfig, default_config
from thermolab.lab.db.models import MethodResultRow, Run, RunStatus, User
from thermolab.lab.runs.request import RunRequest, plan_run
from thermolab.lab.service import Lab
from thermolab.simulation import simulate_first_order

from .test_health import FAST_HASHER

K, TAU = 0.5, 20.0


@pytest.fixture
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Lab]:
    tmp = tmp_path_factory.mktemp("late")
    config = replace(
        default_config(tmp), rigs=(RigConfig("box", "Remote box", "sim:tclab", agent=True),)
    )
    the_lab = Lab(config, hasher=FAST_HASHER)
    the_lab.start()
    the_lab.users.add("ana", "a long enough password", "student")
    yield the_lab
    the_lab.close()


def _interrupted_run(lab: Lab, n: int) -> int:
    """A run as START stored it, interrupted by a restart, with ``n`` samples from its host."""
    request = RunRequest(dt=1.0, samples=n, signal="step:0:10@1", methods=("srm", "lsm"))
    plan = plan_run(request, (0.0, 100.0))
    now = datetime.now(UTC)
    with lab.db.write() as session:
        user_id = session.scalar(select(User.id))
        assert user_id is not None
        run = Run(
            rig_id="box",
            user_id=user_id,
            status=RunStatus.INTERRUPTED.value,
            dt=1.0,
            methods=["srm", "lsm"],
            meta={"settings": plan.settings},
            started_at=now,
            samples_stored=0,
        )
        session.add(run)
        session.flush()
        run_id = run.id
    u = np.where(np.arange(n) >= 1, 10.0, 0.0)
    y = simulate_first_order(u, K, TAU, 1.0)
    samples = [
        SampleOut(
            seq=k + 1,
            run=run_id,
            k=k,
            t=float(k),
            u=float(u[k]),
            y=float(y[k]),
            t_read=float(k),
            jitter=0.0,
            lateness=0.0,
        )
        for k in range(n)
    ]
    lab.agents._store("box", SampleBatch(samples=samples))  # the lab's store, as its endpoint
    return run_id


def test_the_hosts_late_end_stores_each_methods_result_once(lab: Lab) -> None:
    run_id = _interrupted_run(lab, 300)
    end = RunEnded(seq=301, run=run_id, reason="completed", samples=300)
    lab.agents.on_run_ended("box", end)
    lab.agents.on_run_ended("box", end)  # sent again after a lost Ack
    with lab.db.read() as session:
        rows = session.scalar(
            select(func.count())
            .select_from(MethodResultRow)
            .where(MethodResultRow.run_id == run_id)
        )
        status = session.scalar(select(Run.status).where(Run.id == run_id))
    assert rows == 2
    assert status == RunStatus.FINISHED.value
    record = lab.runs.record(run_id)
    assert set(record.results) == {"srm", "lsm"}
    srm = record.results["srm"]["latest"]
    assert srm["k"] == 299
    assert_allclose([srm["K"], srm["tau"]], [K, TAU], rtol=1e-3)
    lsm = record.results["lsm"]
    assert lsm["latest"]["valid"]
    assert "stats" in lsm  # the paper's figures, as an in-process run's end stores them
