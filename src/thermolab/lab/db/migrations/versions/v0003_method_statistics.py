"""Every stored method result carries its statistics (the paper's Tables I/II figures).

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-24

Since this revision the run service computes the statistics once, when a run
ends, and stores them with the result. Results stored earlier lack them; this
migration computes them by replaying each method over the run's stored
samples with its stored settings (the identifiers are deterministic, so this
is the trajectory the run had). Runs still marked running are left alone:
start-up marks them interrupted, and they have no results yet. Nothing is
backfilled on a read any more.
"""

from __future__ import annotations

import logging

import sqlalchemy as sa
from alembic import op

from thermolab.errors import ThermoLabError
from thermolab.jsonsafe import json_safe
from thermolab.lab.runs.statistics import replay_statistics

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | None = None
depends_on: str | None = None

log = logging.getLogger(__name__)

# The tables as this revision knows them (never the models, which may change later).
_runs = sa.table("runs", sa.column("id", sa.Integer), sa.column("dt", sa.Float))
_samples = sa.table(
    "samples",
    sa.column("run_id", sa.Integer),
    sa.column("k", sa.Integer),
    sa.column("u", sa.Float),
    sa.column("y", sa.Float),
)
_results = sa.table(
    "method_results",
    sa.column("id", sa.Integer),
    sa.column("run_id", sa.Integer),
    sa.column("method", sa.String),
    sa.column("params", sa.JSON),
    sa.column("result", sa.JSON),
)


def upgrade() -> None:
    connection = op.get_bind()
    rows = connection.execute(
        sa.select(
            _results.c.id,
            _results.c.run_id,
            _results.c.method,
            _results.c.params,
            _results.c.result,
        ).order_by(_results.c.run_id, _results.c.id)
    ).all()
    samples: dict[int, list[tuple[float, float]]] = {}
    for row_id, run_id, method, params, result in rows:
        if result is None or "stats" in result:
            continue
        dt = connection.scalar(sa.select(_runs.c.dt).where(_runs.c.id == run_id))
        if dt is None:
            continue
        if run_id not in samples:
            samples = {
                run_id: [
                    (u, y)
                    for u, y in connection.execute(
                        sa.select(_samples.c.u, _samples.c.y)
                        .where(_samples.c.run_id == run_id)
                        .order_by(_samples.c.k)
                    )
                ]
            }
        try:
            stats = replay_statistics(
                method, dt, params or {}, result.get("latest"), samples[run_id]
            )
        except ThermoLabError as exc:  # a summary: a run that cannot be replayed keeps its data
            log.warning("run %s: statistics of %s failed: %s", run_id, method, exc)
            continue
        connection.execute(
            sa.update(_results)
            .where(_results.c.id == row_id)
            .values(result={**result, "stats": json_safe(stats)})
        )


def downgrade() -> None:
    # The statistics are a pure function of the stored data; keeping them is harmless.
    pass
