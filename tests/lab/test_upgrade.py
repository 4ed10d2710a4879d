"""Upgrades: two processes making or migrating one SQLite database wait for each other."""

from __future__ import annotations

import threading
from pathlib import Path

from thermolab.lab.accounts.users import UserService
from thermolab.lab.clock import ManualClock
from thermolab.lab.db import Database

from .conftest import FAST_HASHER, PASSWORD


def test_commands_run_while_the_server_makes_the_schema_wait_for_it(tmp_path: Path) -> None:
    # Each Database is what one process has (its own connections and in-process lock):
    # `thermolab serve` making a new database while `thermolab user add` starts.
    url = f"sqlite:///{tmp_path / 'lab.sqlite3'}"
    databases = [Database(url, pool_size=1, max_overflow=1) for _ in range(4)]
    start = threading.Barrier(len(databases))
    failures: list[BaseException] = []

    def command(index: int, db: Database) -> None:
        try:
            start.wait()
            db.upgrade()
            if index:
                UserService(db, ManualClock(), FAST_HASHER).add(f"user{index}", PASSWORD, "student")
        except BaseException as exc:  # reported below, with the others
            failures.append(exc)

    threads = [threading.Thread(target=command, args=pair) for pair in enumerate(databases)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60)
    for db in databases:
        db.close()
    assert failures == []
    check = Database(url)
    assert [u.username for u in UserService(check, ManualClock(), FAST_HASHER).list()] == [
        "user1",
        "user2",
        "user3",
    ]
    check.close()
