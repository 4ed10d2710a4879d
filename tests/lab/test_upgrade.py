"""Upgrades: two processes making or migrating one SQLite database wait for each other."""

from __future__ import annotations

import contextlib
import shutil
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import alembic.command
import httpx
import pytest
from alembic.config import Config
from sqlalchemy import (
    JSON,
    Boolean,
    Column,
    Connection,
    DateTime,
    Float,
    Integer,
    LargeBinary,
    MetaData,
    Numeric,
    String,
    func,
    insert,
    select,
)

from thermolab.lab.accounts.users import UserService
from thermolab.lab.clock import ManualClock
from thermolab.lab.db import MIGRATIONS_DIR, Database
from thermolab.lab.operations.backup import head_revision, known_revisions

from .conftest import FAST_HASHER, PASSWORD


def test_commands_run_while_the_server_makes_the_schema_wait_for_it(tmp_path: Path) -> None:
    # Each Database is what one process has (its own connections and in-process lock):
    # `thermolab serve` making a new database while `thermolab user add` starts.
    url = f"sqlite:///{tmp_path / 'lab.sqlite3'}"

    def command(index: int, db: Database) -> None:
        db.upgrade()
        if index:
            UserService(db, ManualClock(), FAST_HASHER).add(f"user{index}", PASSWORD, "student")

    assert _at_once(url, command) == []
    check = Database(url)
    assert [u.username for u in UserService(check, ManualClock(), FAST_HASHER).list()] == [
        "user1",
        "user2",
        "user3",
    ]
    check.close()


def test_connections_opening_a_new_database_at_once_all_open(tmp_path: Path) -> None:
    """Each new connection puts SQLite in WAL mode; two asking at once on a new file made
    SQLite refuse one at once ("database is locked", 20 rounds of 300 before the fix)."""
    failures = [
        failure
        for round_ in range(100)
        for failure in _at_once(
            f"sqlite:///{tmp_path / f'new{round_}.sqlite3'}",
            lambda _, db: db.engine.connect().close(),
        )
    ]
    assert failures == []


def _at_once(url: str, work: Callable[[int, Database], object]) -> list[BaseException]:
    """``work(index, db)`` in four threads at once, each with its own Database of ``url``
    (what one process has: its own connections and in-process lock); what they raised."""
    databases = [Database(url, pool_size=1, max_overflow=1) for _ in range(4)]
    start = threading.Barrier(len(databases))
    failures: list[BaseException] = []

    def one(index: int, db: Database) -> None:
        try:
            start.wait()
            work(index, db)
        except BaseException as exc:  # reported by the caller, with the others
            failures.append(exc)

    threads = [threading.Thread(target=one, args=pair) for pair in enumerate(databases)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60)
    for db in databases:
        db.close()
    return failures


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


@pytest.mark.slow
def test_serve_and_user_add_started_together_on_a_new_database_both_succeed(
    tmp_path: Path,
) -> None:
    # The report of issue #26: `thermolab serve` exited with "database is locked" when
    # `thermolab user add` ran as it made a new SQLite database's schema. Real processes,
    # started together on a data folder with no database yet.
    thermolab = (sys.executable, "-m", "thermolab", "--data-dir", str(tmp_path / "data"))
    port = _free_port()
    server = subprocess.Popen(
        [*thermolab, "serve", "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        adds = [
            subprocess.Popen(
                [*thermolab, "user", "add", name, "--role", role, "--password-stdin"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            for name, role in (("root", "admin"), ("ana", "student"))
        ]
        answers = [add.communicate(PASSWORD, timeout=120) for add in adds]
        assert [add.returncode for add in adds] == [0, 0], answers
        deadline = time.monotonic() + 60
        while True:
            assert server.poll() is None, server.communicate()[1]
            with contextlib.suppress(httpx.HTTPError):
                if httpx.get(f"http://127.0.0.1:{port}/readyz", timeout=2).status_code == 200:
                    break
            assert time.monotonic() < deadline, "the server did not become ready"
            time.sleep(0.1)
        login = {"username": "ana", "password": PASSWORD}
        answer = httpx.post(f"http://127.0.0.1:{port}/api/session", json=login, timeout=10)
        assert answer.status_code == 200, answer.text
    finally:
        server.terminate()
        _, err = server.communicate(timeout=60)
    assert "locked" not in err, err


# -- the ladder: a database at every earlier revision, with rows, upgraded to head ---------

# Values for columns whose CHECK constraints or migrations want a real one; every other
# column gets a value of its type (nullable ones too: the upgrade must carry them).
_VALUES: dict[str, Any] = {
    "role": "student",
    "status": "finished",
    "power_state": "off",
    "end_reason": None,
    "leave_reason": None,
    "kind": "input",
    "method": "lsm",
}
_TABLE_VALUES: dict[tuple[str, str], Any] = {
    ("control_sessions", "ended_at"): None,
    ("queue_entries", "left_at"): None,
    ("users", "username"): "ana",
    ("rigs", "id"): "twin",
    ("bookings", "ends_at"): datetime(2026, 3, 2, 14, 0),
    ("lti_grades", "status"): "pending",
    ("lti_handoffs", "kind"): "window",
    ("rig_power_changes", "state"): "on",
}


def _value(table: str, column: Column[Any]) -> Any:
    if (table, column.name) in _TABLE_VALUES:
        return _TABLE_VALUES[(table, column.name)]
    if column.name in _VALUES:
        return _VALUES[column.name]
    kind = column.type
    if isinstance(kind, JSON):
        return {}
    if isinstance(kind, Boolean):
        return False
    if isinstance(kind, Integer):
        return 1
    if isinstance(kind, Float | Numeric):
        return 1.5
    if isinstance(kind, DateTime):
        return datetime(2026, 3, 2, 12, 0)
    if isinstance(kind, LargeBinary):
        return b"\x89PNG"
    if isinstance(kind, String):
        length = getattr(kind, "length", None) or 40
        return f"{column.name}1"[:length]
    raise AssertionError(f"no test value for {table}.{column.name} ({kind!r})")


def _fill(connection: Connection) -> dict[str, dict[str, Any]]:
    """One row in every table (samples: three), foreign keys pointing at those rows."""
    metadata = MetaData()
    metadata.reflect(connection)
    rows: dict[str, dict[str, Any]] = {}
    for table in metadata.sorted_tables:
        if table.name == "alembic_version":
            continue
        row: dict[str, Any] = {}
        for column in table.columns:
            keys = list(column.foreign_keys)
            if keys:
                target = keys[0].column
                row[column.name] = rows[target.table.name][target.name]
            else:
                row[column.name] = _value(table.name, column)
        connection.execute(insert(table).values(row))
        rows[table.name] = row
        if table.name == "samples":
            for k in (2, 3):
                more = {"k": k} | ({"id": k} if "id" in table.c else {})
                connection.execute(insert(table).values({**row, **more}))
    return rows


def _migrate(db: Database, revision: str) -> None:
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    with db.engine.begin() as connection:
        config.attributes["connection"] = connection
        alembic.command.upgrade(config, revision)


_CHANGED_BY_MIGRATIONS = {("method_results", "result")}  # v0003 adds the statistics


_EARLIER = known_revisions()[:-1]


@pytest.fixture(scope="module")
def sqlite_at(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """An empty SQLite database at each earlier revision, made by one walk up the ladder."""
    folder = tmp_path_factory.mktemp("ladder")
    walker = folder / "walk.sqlite3"
    db = Database(f"sqlite:///{walker}", pool_size=1, max_overflow=0)
    made = {}
    try:
        for revision in _EARLIER:
            _migrate(db, revision)
            made[revision] = folder / f"{revision}.sqlite3"
            with db.engine.connect() as connection:
                raw = connection.connection.driver_connection
                assert isinstance(raw, sqlite3.Connection)
                target = sqlite3.connect(made[revision])
                raw.backup(target)
                target.close()
    finally:
        db.close()
    return made


@pytest.mark.parametrize(
    ("revision", "backend"),
    [(revision, "sqlite") for revision in _EARLIER]
    # PostgreSQL takes 3-4 s a rung: the first, which runs every migration over data.
    + [pytest.param(_EARLIER[0], "postgres", marks=pytest.mark.postgres)],
)
def test_a_database_at_every_earlier_revision_upgrades_with_its_data(
    revision: str, backend: str, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    if backend == "sqlite":
        shutil.copyfile(request.getfixturevalue("sqlite_at")[revision], tmp_path / "old.sqlite3")
        database_url = f"sqlite:///{tmp_path / 'old.sqlite3'}"
    else:
        database_url = request.getfixturevalue("postgres_url")
    db = Database(database_url, pool_size=1, max_overflow=0)
    try:
        if backend != "sqlite":
            _migrate(db, revision)
        with db.engine.begin() as connection:
            before = _fill(connection)
        db.upgrade()
        assert db.current_revision() == head_revision()
        metadata = MetaData()
        metadata.reflect(db.engine)
        with db.engine.connect() as connection:
            for name, row in before.items():
                table = metadata.tables[name]
                count = connection.scalar(select(func.count()).select_from(table))
                assert count == (3 if name == "samples" else 1), name
                kept = {
                    c: v
                    for c, v in row.items()
                    if c in table.c and (name, c) not in _CHANGED_BY_MIGRATIONS
                }
                found = connection.execute(
                    select(*(table.c[c] for c in kept)).order_by(*table.primary_key.columns)
                ).first()
                assert found is not None
                read = dict(zip(kept, found, strict=True))
                assert _naive(read) == _naive(kept), name
    finally:
        db.close()


def _naive(row: dict[str, Any]) -> dict[str, Any]:
    """Datetimes as naive UTC: PostgreSQL's come back aware, SQLite's naive."""
    return {
        key: value.astimezone(UTC).replace(tzinfo=None)
        if isinstance(value, datetime) and value.tzinfo is not None
        else value
        for key, value in row.items()
    }


def test_serve_says_which_migrations_it_runs_on_an_old_database(
    tmp_path: Path, sqlite_at: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    from thermolab.cli.serve import _announce_upgrade
    from thermolab.lab.config import default_config

    config = default_config(tmp_path)
    shutil.copyfile(sqlite_at["0012"], tmp_path / "thermolab.sqlite3")
    _announce_upgrade(config)
    head = head_revision()
    assert capsys.readouterr().err.strip() == (
        f"database: upgrading its schema from revision 0012 to {head} "
        f"({int(head) - 12} migrations, in one transaction; other commands wait for it)"
    )
    db = Database(config.database)
    db.upgrade()
    db.close()
    _announce_upgrade(config)  # nothing to say at head
    assert capsys.readouterr().err == ""
