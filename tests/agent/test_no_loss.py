"""No sample lost, none stored twice, across any pattern of link losses (Hypothesis).

The agent's real outbox (SQLite) and framing (``outbox_frames``), the lab's
real store (``AgentHub``'s idempotent insert into the lab's database) and
the real protocol decoder; what Hypothesis chooses is the interleaving: when
samples are taken, how much of the outbox a connection sends before it
breaks, whether the lab's Ack reaches the agent, how often the link is lost.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sqlalchemy import delete, select

from thermolab.agent.link import outbox_frames
from thermolab.agent.outbox import Outbox
from thermolab.agent.protocol import RunEnded, SampleBatch, SampleOut, decode_agent
from thermolab.lab.config import RigConfig, default_config
from thermolab.lab.db.models import Run, Sample, User
from thermolab.lab.service import Lab

from .test_health import FAST_HASHER

# One step: ("take", n samples) | ("send", rows before the link breaks, ack arrives?) | ("lose",)
_steps = st.lists(
    st.one_of(
        st.tuples(st.just("take"), st.integers(1, 30)),
        st.tuples(st.just("send"), st.integers(0, 60), st.booleans()),
        st.tuples(st.just("lose")),
    ),
    max_size=40,
)


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Lab]:
    tmp = tmp_path_factory.mktemp("noloss")
    config = replace(
        default_config(tmp), rigs=(RigConfig("box", "Remote box", "sim:tclab", agent=True),)
    )
    the_lab = Lab(config, hasher=FAST_HASHER)
    the_lab.start()
    user = the_lab.users.add("ana", "a long enough password", "student")
    with the_lab.db.write() as session:
        assert session.get(User, user.id) is not None
    yield the_lab
    the_lab.close()


def _new_run(lab: Lab) -> int:
    now = datetime.now(UTC)
    with lab.db.write() as session:
        session.execute(delete(Run))
        user_id = session.scalar(select(User.id))
        assert user_id is not None
        run = Run(
            rig_id="box",
            user_id=user_id,
            status="running",
            dt=0.1,
            methods=[],
            meta={},
            started_at=now,
            samples_stored=0,
        )
        session.add(run)
        session.flush()
        return run.id


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(steps=_steps)
def test_every_sample_is_stored_once_whatever_the_link_does(
    lab: Lab, tmp_path: Path, steps: list[tuple[object, ...]]
) -> None:
    run_id = _new_run(lab)
    box = Outbox(":memory:")
    k = 0
    sent = 0  # the connection's cursor: a new connection starts again from 0
    for step in steps:
        if step[0] == "take":
            for _ in range(int(step[1])):  # type: ignore[call-overload]
                sample = SampleOut(
                    seq=1,
                    run=run_id,
                    k=k,
                    t=k * 0.1,
                    u=1.0,
                    y=20.0 + k,
                    t_read=k * 0.1,
                    jitter=0.0,
                    lateness=0.0,
                )
                box.append("sample", sample.model_dump_json(exclude={"seq"}))
                k += 1
        elif step[0] == "lose":
            sent = 0
        else:
            limit, acked = int(step[1]), bool(step[2])  # type: ignore[call-overload]
            rows = box.pending(sent, limit)
            for frame in outbox_frames(rows):
                message = decode_agent(frame)
                assert isinstance(message, SampleBatch | RunEnded)
                if isinstance(message, SampleBatch):
                    lab.agents._store("box", message)  # the lab's store, as its endpoint calls it
                    if acked:
                        box.ack(message.samples[-1].seq)
            if rows:
                sent = rows[-1][0]
            if not acked:
                sent = 0  # the Ack was lost with the link: the next connection resends
    # The link comes back for good: everything left goes, and is acknowledged.
    for frame in outbox_frames(box.pending(0, 10**6)):
        message = decode_agent(frame)
        assert isinstance(message, SampleBatch)
        lab.agents._store("box", message)
        box.ack(message.samples[-1].seq)
    assert box.count() == 0
    # Another rig's host cannot write into this rig's run.
    intruder = SampleOut(
        seq=1, run=run_id, k=k, t=0.0, u=0.0, y=0.0, t_read=0.0, jitter=0.0, lateness=0.0
    )
    lab.agents._store("elsewhere", SampleBatch(samples=[intruder]))
    with lab.db.read() as session:
        stored = list(
            session.scalars(select(Sample.k).where(Sample.run_id == run_id).order_by(Sample.k))
        )
        count = session.scalar(select(Run.samples_stored).where(Run.id == run_id))
    assert stored == list(range(k))  # none lost, none twice, in order
    assert count == k


def _sample(run_id: int, k: int, y: float = 20.0) -> SampleOut:
    t = k * 0.1
    return SampleOut(
        seq=k + 1, run=run_id, k=k, t=t, u=1.0, y=y, t_read=t, jitter=0.0, lateness=0.0
    )


def test_a_host_cannot_write_past_the_samples_asked_for_nor_into_a_closed_run(
    lab: Lab, caplog: pytest.LogCaptureFixture
) -> None:
    run_id = _new_run(lab)
    with lab.db.write() as session:
        run = session.get(Run, run_id)
        assert run is not None
        run.n_samples = 5
    lab.agents._store("box", SampleBatch(samples=[_sample(run_id, k) for k in range(5)]))
    # Past the 5 asked for: refused, and said (a negative number never decodes).
    lab.agents._store("box", SampleBatch(samples=[_sample(run_id, 5, 999.0)]))
    assert "refused 1 of 1 samples" in caplog.text
    # Interrupted by the lab (a restart): the host may still upload what it took before.
    with lab.db.write() as session:
        run = session.get(Run, run_id)
        assert run is not None
        run.n_samples, run.status = 10, "interrupted"
    lab.agents._store("box", SampleBatch(samples=[_sample(run_id, 5)]))
    # Its own end stored: the run is closed for writing, whatever the host sends.
    with lab.db.write() as session:
        run = session.get(Run, run_id)
        assert run is not None
        run.status = "stopped"
    lab.agents._store("box", SampleBatch(samples=[_sample(run_id, k, 999.0) for k in (6, 7)]))
    with lab.db.read() as session:
        rows = session.execute(select(Sample.k, Sample.y).where(Sample.run_id == run_id))
        stored = dict(rows.all())
        count = session.scalar(select(Run.samples_stored).where(Run.id == run_id))
    assert sorted(stored) == [0, 1, 2, 3, 4, 5]
    assert 999.0 not in stored.values()
    assert count == 6
