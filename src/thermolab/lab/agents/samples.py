"""A rig host's samples into the database: only its rig's open runs, each sample once.

:func:`store_samples` is what :class:`~thermolab.lab.agents.hub.AgentHub` does
with every :class:`~thermolab.agent.protocol.SampleBatch` before it acks it.
"""

from __future__ import annotations

import logging
import math
from typing import Any

from sqlalchemy import func, select, update
from sqlalchemy.dialects import postgresql, sqlite

from thermolab.agent.protocol import SampleBatch
from thermolab.lab.db import Database
from thermolab.lab.db.models import Run, RunStatus, Sample

__all__ = ["OPEN_FOR_SAMPLES", "store_samples"]

log = logging.getLogger(__name__)

#: Runs a host may still write samples into (see :func:`store_samples`).
OPEN_FOR_SAMPLES = (RunStatus.RUNNING.value, RunStatus.INTERRUPTED.value)


def _within(row: dict[str, Any], asked: dict[int, int | None]) -> bool:
    """A sample of an open run of the rig, numbered within what was asked, at a real time."""
    if row["run_id"] not in asked:
        return False
    limit = asked[row["run_id"]]
    k, t = row["k"], row["t"]
    return k >= 0 and (limit is None or k < limit) and math.isfinite(t) and t >= 0.0


def store_samples(db: Database, rig_id: str, batch: SampleBatch) -> None:
    """Store a host's batch: only samples of this rig's open runs, within what was asked.

    Idempotent (a batch sent again after a lost Ack stores nothing twice); a
    refused sample is logged, never stored.
    """
    rows = [
        {
            "run_id": s.run,
            "k": s.k,
            "t": s.t,
            "u": s.u,
            "y": s.y,
            "t_read": s.t_read,
            "jitter": s.jitter,
            "lateness": s.lateness,
            "extra": s.extra,
        }
        for s in batch.samples
    ]
    runs = {s.run for s in batch.samples}
    with db.write() as session:
        # Only this rig's runs (not another rig's, nor a deleted one), and only runs open
        # for writing: going, or interrupted by the lab while the host may still upload
        # what it took before its own end. The host's end comes after its samples (one
        # outbox, in order), so once it is stored the run is closed.
        mine = select(Run.id, Run.n_samples).where(
            Run.id.in_(runs), Run.rig_id == rig_id, Run.status.in_(OPEN_FOR_SAMPLES)
        )
        asked: dict[int, int | None] = dict(session.execute(mine).all())
        taken = [r for r in rows if _within(r, asked)]
        if len(taken) < len(rows):
            log.warning(
                "rig host %s: refused %d of %d samples (runs %s: not this rig's, closed, "
                "or past the samples asked for)",
                rig_id, len(rows) - len(taken), len(rows), sorted(runs),
            )  # fmt: skip
        rows = taken
        known = {r["run_id"] for r in rows}
        if rows:
            dialect = session.get_bind().dialect.name
            insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
            session.execute(insert(Sample).on_conflict_do_nothing(), rows)
        for run_id in known:
            count = select(func.count()).select_from(Sample).where(Sample.run_id == run_id)
            session.execute(
                update(Run).where(Run.id == run_id).values(samples_stored=count.scalar_subquery())
            )
