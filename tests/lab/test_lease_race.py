"""Never two owners: processes racing for a free database lease, exactly one wins.

The fleet's takeover rests on the lease (:mod:`thermolab.lab.fleet.lease`): when
the owner is gone, every follower may try to take it at the same moment.
Each contender here is a :class:`DatabaseLease` of its own (its own token,
its own connection from the pool) on a thread released by one barrier; the
lease is missing (no row yet), run out, or held by a dead process of this
host. Hypothesis varies the number of contenders and the lease's state, on
SQLite and PostgreSQL: exactly one acquires, every other gets
:class:`LeaseHeldError` (nothing else), and the row names the winner.
"""

from __future__ import annotations

import subprocess
import sys
import threading
from datetime import timedelta

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from thermolab.lab.clock import ManualClock
from thermolab.lab.db import Database
from thermolab.lab.db.models import ServerLease
from thermolab.lab.fleet.lease import LEASE_TTL, DatabaseLease, LeaseHeldError

_DEAD_PID = int(
    subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
)


def _set_lease(db: Database, clock: ManualClock, state: str) -> None:
    with db.write() as session:
        lease = session.get(ServerLease, 1)
        if lease is not None:
            session.delete(lease)
        if state == "missing":
            return
        session.flush()
        holder = DatabaseLease(db, clock)
        run_out = state == "run out"
        session.add(
            ServerLease(
                id=1,
                host="elsewhere.example" if run_out else holder.host,
                pid=12345 if run_out else _DEAD_PID,
                token="the-old-owner",
                acquired_at=clock.now() - timedelta(hours=1),
                expires_at=clock.now() - (timedelta(seconds=1) if run_out else -LEASE_TTL),
            )
        )


@pytest.mark.slow
@settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    contenders=st.integers(min_value=2, max_value=6),
    state=st.sampled_from(["missing", "run out", "holder dead"]),
)
def test_racing_for_a_free_lease_leaves_exactly_one_owner(
    database_url: str, contenders: int, state: str
) -> None:
    clock = ManualClock()
    db = Database(database_url, pool_size=contenders, max_overflow=2)
    try:
        _set_lease(db, clock, state)
        leases = [DatabaseLease(db, clock) for _ in range(contenders)]
        barrier = threading.Barrier(contenders)
        outcomes: list[object] = [None] * contenders

        def race(i: int) -> None:
            barrier.wait()
            try:
                leases[i].acquire()
                outcomes[i] = "won"
            except Exception as exc:  # the outcome is the assertion's business
                outcomes[i] = exc

        threads = [threading.Thread(target=race, args=(i,)) for i in range(contenders)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(timeout=60)
        winners = [i for i, outcome in enumerate(outcomes) if outcome == "won"]
        assert len(winners) == 1, outcomes
        losers = [o for i, o in enumerate(outcomes) if i != winners[0]]
        assert all(isinstance(o, LeaseHeldError) for o in losers), outcomes
        with db.read() as session:
            row = session.get(ServerLease, 1)
            assert row is not None
            assert row.token == leases[winners[0]].token
        assert [lease.held for lease in leases].count(True) == 1
        # The losers still cannot take it from a live, renewing winner.
        assert leases[winners[0]].renew()
        with pytest.raises(LeaseHeldError):
            leases[(winners[0] + 1) % contenders].acquire()
    finally:
        db.close()
