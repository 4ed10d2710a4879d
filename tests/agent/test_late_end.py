"""A rig host's end of a run the lab restarted under: its results, stored once.

In-process and quick beside tests/agent/test_restart.py (real processes): the
run row as START stores it, marked interrupted as a restart leaves it, the
host's samples stored by the lab's own store, then the host's ``RunEnded``
as the lab's endpoint hands it on, twice (a resend after a lost Ack). The
end stores the run's timing as an in-process run's end does, judged on the
timing each stored sample came with (a real rig's late samples show).
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
from thermolab.lab.access.queries import SERVER_STOPPED
from thermolab.lab.config import RigConfig, default_config
from thermolab.lab.db.models import MethodResultRow, Run, RunStatus, User
from thermolab.lab.runs.request import RunRequest, plan_run
from thermolab.lab.runs.timing import timing_summary
from thermolab.lab.service import Lab
from thermolab.simulation import simulate_first_order

from .test_health import FAST_HASHER

K, TAU = 0.5, 20.0


@pytest.fixture
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Lab]:
    tmp = tmp_path_factory.mktemp("late")
    config = replace(
        default_config(tmp),
        rigs=(
            RigConfig("box", "Remote box", "sim:tclab", agent=True),
            RigConfig("kit", "Remote kit", "tclab", agent=True),
        ),
    )
    the_lab = Lab(config, hasher=FAST_HASHER)
    the_lab.start()
    the_lab.users.add("ana", "a long enough password", "student")
    yield the_lab
    the_lab.close()


def _interrupted_run(
    lab: Lab, n: int, rig: str = "box", late: np.ndarray | None = None, reason: str | None = None
) -> int:
    """A run as START stored it, interrupted by a restart, with ``n`` samples from its host.

    ``late``: each sample's lateness (s) as the host's runner measured it (default none),
    its reading taken that late.
    """
    lateness = np.zeros(n) if late is None else late
    request = RunRequest(dt=1.0, samples=n, signal="step:0:10@1", methods=("srm", "lsm"))
    plan = plan_run(request, (0.0, 100.0))
    now = datetime.now(UTC)
    with lab.db.write() as session:
        user_id = session.scalar(select(User.id))
        assert user_id is not None
        run = Run(
            rig_id=rig,
            user_id=user_id,
            status=RunStatus.INTERRUPTED.value,
            end_reason=reason,
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
            t_read=float(k + lateness[k]),
            jitter=float(lateness[k] - lateness[k - 1]) if k else 0.0,
            lateness=float(lateness[k]),
        )
        for k in range(n)
    ]
    lab.agents._store(rig, SampleBatch(samples=samples))  # the lab's store, as its endpoint
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
    # Its timing, judged as an in-process run's end judges it: a twin's (exact) data.
    timing = record.timing
    assert timing is not None
    assert timing.keys() == timing_summary([], [], 1.0, simulated=True).keys()
    assert (timing["rig"], timing["maxLateness"], timing["p95Lateness"]) == ("twin", None, None)
    assert timing["periodSpread"] == 0.0
    assert timing["warnings"] == []


def test_the_late_end_of_a_real_rigs_run_shows_its_late_samples(lab: Lab) -> None:
    # Every tenth reading 0.3 s late (the host's computer busy), the others on time.
    late = np.where(np.arange(100) % 10 == 5, 0.3, 0.002)
    run_id = _interrupted_run(lab, 100, rig="kit", late=late)
    lab.agents.on_run_ended("kit", RunEnded(seq=101, run=run_id, reason="completed", samples=100))
    timing = lab.runs.record(run_id).timing
    assert timing is not None
    assert timing["rig"] == "real"
    assert timing["maxLateness"] == pytest.approx(0.3)
    assert 0.002 <= timing["p95Lateness"] <= 0.3
    # Periods of 1.298 and 0.702 s among 1 s ones spread ~13 %: over the 5 % limit.
    assert timing["periodSpread"] == pytest.approx(
        timing_summary(np.arange(100) + late, late, 1.0, simulated=False)["periodSpread"]
    )
    assert timing["periodSpread"] > 0.05
    assert timing["warnings"][0].startswith("timing jitter: the sample period spreads")


@pytest.mark.parametrize(
    ("interrupted", "stored"),
    [
        # The lab's server stopped during the run (its restart stored it so): the host lost
        # its link because the owner went, whatever an older host's words say.
        (SERVER_STOPPED, "owner_gone: link to the lab lost for over 30 s"),
        (None, "link_lost: link to the lab lost for over 30 s"),
    ],
)
def test_a_late_end_for_a_lost_link_names_the_owner_gone_when_the_server_stopped(
    lab: Lab, interrupted: str | None, stored: str
) -> None:
    run_id = _interrupted_run(lab, 20, reason=interrupted)
    message = "link to the lab lost for over 30 s"
    lab.agents.on_run_ended(
        "box", RunEnded(seq=21, run=run_id, reason="ended", message=message, samples=20)
    )
    record = lab.runs.record(run_id)
    assert (record.status, record.end_reason) == ("stopped", stored)
