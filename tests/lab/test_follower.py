"""A standby follower's promotion, in process: the lease lapses, one standby owns, no turn ends.

The owner is a lab holding the lease that stops renewing it (as a killed
process does); the followers are :class:`FollowerLab` on the same database
and the same manual clock, on SQLite and PostgreSQL. A standby does not take
a lease still in force; once it has run out exactly one of two standbys
takes it, a plain follower never does, the controller and the queue are the
same, and the old owner's next renewal finds the lease lost. The same with
real processes and a killed owner: tests/lab/test_takeover.py.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.fleet.follower import FollowerLab
from thermolab.lab.fleet.lease import LEASE_TTL
from thermolab.lab.rigs.opener import device_opener
from thermolab.lab.service import Lab

from .conftest import FAST_HASHER, PASSWORD, make_config


@pytest.fixture
def config(tmp_path: Path, database_url: str) -> LabConfig:
    return make_config(tmp_path, database_url)


@pytest.fixture
def labs() -> Iterator[list[Lab]]:
    made: list[Lab] = []
    yield made
    for lab in made:
        lab.close()


def _follower(config: LabConfig, clock: ManualClock, labs: list[Lab], standby: bool) -> FollowerLab:
    lab = FollowerLab(
        config,
        standby=standby,
        clock=clock,
        hasher=FAST_HASHER,
        opener=device_opener(),
        database=Database(config.database),
    )
    lab.start()
    labs.append(lab)
    return lab


def test_one_standby_takes_a_lapsed_lease_and_the_same_student_controls(
    config: LabConfig, clock: ManualClock, labs: list[Lab]
) -> None:
    owner = Lab(
        config,
        clock=clock,
        hasher=FAST_HASHER,
        opener=device_opener(),
        database=Database(config.database),
        exclusive=True,
    )
    owner.start()
    labs.append(owner)
    people = {}
    for name in ("ana", "bo"):
        info = owner.users.add(name, PASSWORD, "student")
        people[name] = Principal(info.id, info.username, info.role)
    owner.access.request_control("twin", people["ana"])
    owner.access.request_control("twin", people["bo"])  # queued behind ana
    turn = owner.access.caller_turn("twin", people["ana"].user_id)
    assert turn is not None
    plain = _follower(config, clock, labs, standby=False)
    standbys = [_follower(config, clock, labs, standby=True) for _ in range(2)]

    # The owner renews (its sweep): no standby takes a lease in force.
    owner.sweep()
    assert [lab.promote() for lab in standbys] == [False, False]
    # The owner stops renewing (killed); once the lease has run out, one standby owns.
    clock.advance(LEASE_TTL.total_seconds() + 1)
    assert plain.promote() is False
    promoted = [lab.promote() for lab in standbys]
    assert sorted(promoted) == [False, True]
    winner = standbys[promoted.index(True)]
    loser = standbys[promoted.index(False)]
    assert winner.owner
    assert not loser.owner
    assert not plain.owner
    assert winner.hub.driver("twin") is not None  # its devices are open
    assert plain.hub.driver("twin") is None
    # The same turn, the same queue: nothing ended.
    assert winner.access.caller_turn("twin", people["ana"].user_id) == turn
    assert winner.access.view("twin", people["ana"]).access.role == "controller"
    assert winner.access.view("twin", people["bo"]).access.role == "queued"
    # The winner renews from now on; the loser and the old owner find it taken.
    for _ in range(2):  # ana's page heartbeats, the winner sweeps
        clock.advance(LEASE_TTL.total_seconds() / 2 + 0.5)
        winner.access.view("twin", people["ana"])
        winner.sweep()
    assert loser.promote() is False
    assert owner.lease is not None
    assert not owner.lease.lost
    owner.sweep()
    assert owner.lease.lost  # the fleet stops such a worker (lab/fleet/workers.py)
    assert winner.access.caller_turn("twin", people["ana"].user_id) == turn
