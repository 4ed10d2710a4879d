"""Storage: migrations on a fresh database, schema equals the models, the last line of defence."""

from __future__ import annotations

import sqlite3
import threading
import time
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import pytest
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import event, text
from sqlalchemy.exc import IntegrityError

from thermolab.errors import ConfigError
from thermolab.lab.db import Database, normalize_database_url
from thermolab.lab.db.models import Base, ControlSession, QueueEntry, RigRow, User, UTCDateTime

TABLES = {
    # issue #24, item 7: the booking tools (thermolab.lab.db.booking_tool_models)
    "course_booking_quotas",
    "calendar_feeds",
    "reminder_addresses",
    "reminders_sent",
    "audit_log",  # issue #25: privileged actions (thermolab.lab.db.audit_models)
    "agent_hosts",  # issue #14: rig hosts (thermolab.lab.db.agent_models)
    "users",
    "courses",
    "course_members",
    "course_rigs",
    "sessions",
    "rigs",
    "control_sessions",
    "queue_entries",
    "runs",
    "samples",
    "commands",
    "guide_pages",
    "guide_revisions",
    "server_lease",
    "api_tokens",
    "method_results",
    "rig_settings",
    "assignments",
    "submissions",
    # Grading tools (issue #24 item 7): overrides, extensions, lab groups.
    "grade_overrides",
    "deadline_extensions",
    "lab_groups",
    "lab_group_members",
    "bookings",
    "booking_rigs",
    "rig_power_changes",
    # LTI 1.3 (issue #12).
    "lti_platforms",
    "lti_keys",
    "lti_login_states",
    "lti_identities",
    "lti_contexts",
    "lti_resource_links",
    "lti_grades",
    "lti_handoffs",
    # Limits per course (issue #10, item 3).
    "course_settings",
    # Pictures of the guide pages (issue #10, item 1).
    "guide_images",
}


@pytest.fixture(
    params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)],
)
def fresh_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A database that has never been migrated."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'fresh.sqlite3'}"
    url: str = request.getfixturevalue("postgres_url")
    return url


def test_migrations_create_the_schema_of_the_models(fresh_url: str) -> None:
    db = Database(fresh_url, pool_size=1, max_overflow=0)
    try:
        assert db.current_revision() is None
        db.upgrade()
        db.upgrade()  # idempotent
        assert db.current_revision() == "0023"
        assert set(db.table_names()) == TABLES | {"alembic_version"}
        with db.engine.connect() as connection:
            context = MigrationContext.configure(connection, opts={"compare_type": True})
            assert compare_metadata(context, Base.metadata) == []
    finally:
        db.close()


def _now() -> datetime:
    return datetime(2026, 1, 1, tzinfo=UTC)


def _seed(db: Database) -> tuple[int, int]:
    now = _now()
    with db.write() as session:
        session.add(
            RigRow(
                id="twin",
                title="Twin",
                spec="sim",
                configured=True,
                in_service=True,
                power_state="on",
                power_changed_at=now,
                needs_cooldown=False,
                next_ticket=1,
                created_at=now,
                updated_at=now,
            )
        )
        users = [
            User(
                username=name,
                role="student",
                password_hash="x",
                created_at=now,
                password_changed_at=now,
            )
            for name in ("ana", "ben")
        ]
        session.add_all(users)
        session.flush()
        return users[0].id, users[1].id


def _control(rig: str, user: int, name: str) -> ControlSession:
    now = _now()
    return ControlSession(
        rig_id=rig,
        user_id=user,
        username=name,
        started_at=now,
        deadline=now + timedelta(seconds=300),
        last_heartbeat_at=now,
        last_activity_at=now,
    )


def test_the_database_refuses_a_second_active_controller(database_url: str) -> None:
    db = Database(database_url, pool_size=1, max_overflow=1)
    try:
        ana, ben = _seed(db)
        with db.write() as session:
            session.add(_control("twin", ana, "ana"))
        with pytest.raises(IntegrityError, match=r"(?i)unique"), db.write() as session:
            session.add(_control("twin", ben, "ben"))
        with db.write() as session:  # once the first has ended, a new one may start
            first = session.query(ControlSession).one()
            first.ended_at = _now()
            first.end_reason = "released"
            session.add(_control("twin", ben, "ben"))
    finally:
        db.close()


def test_the_database_refuses_duplicate_tickets_and_double_queueing(database_url: str) -> None:
    db = Database(database_url, pool_size=1, max_overflow=1)
    now = _now()
    try:
        ana, ben = _seed(db)

        def entry(user: int, ticket: int) -> QueueEntry:
            return QueueEntry(
                rig_id="twin", user_id=user, ticket=ticket, joined_at=now, last_heartbeat_at=now
            )

        with db.write() as session:
            session.add(entry(ana, 1))
        with pytest.raises(IntegrityError), db.write() as session:
            session.add(entry(ben, 1))
        with pytest.raises(IntegrityError), db.write() as session:
            session.add(entry(ana, 2))
        with pytest.raises(IntegrityError), db.write() as session:
            session.add(  # an end without a reason
                ControlSession(
                    rig_id="twin",
                    user_id=ben,
                    username="ben",
                    started_at=now,
                    deadline=now,
                    last_heartbeat_at=now,
                    last_activity_at=now,
                    ended_at=now,
                )
            )
    finally:
        db.close()


def test_instants_come_back_as_utc_on_every_backend(database_url: str) -> None:
    db = Database(database_url, pool_size=1, max_overflow=0)
    try:
        _seed(db)
        local = datetime(2026, 1, 1, 3, 30, tzinfo=timezone(timedelta(hours=2)))
        with db.write() as session:
            rig = session.get(RigRow, "twin")
            assert rig is not None
            rig.vacant_since = local
        with db.read() as session:
            rig = session.get(RigRow, "twin")
            assert rig is not None
            assert rig.vacant_since == datetime(2026, 1, 1, 1, 30, tzinfo=UTC)
            assert rig.vacant_since.tzinfo is UTC
        with pytest.raises(ValueError, match="naive"):
            UTCDateTime().process_bind_param(datetime(2026, 1, 1), db.engine.dialect)
    finally:
        db.close()


def test_sqlite_runs_in_wal_mode_with_foreign_keys_and_a_busy_timeout(tmp_path: Path) -> None:
    db = Database(f"sqlite:///{tmp_path / 'lab.sqlite3'}")
    db.upgrade()
    with db.engine.connect() as connection:
        assert connection.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert connection.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        assert connection.exec_driver_sql("PRAGMA busy_timeout").scalar() == 30000
    db.close()
    # A writer of another process holds the lock for a moment: ours waits, then succeeds.
    other = sqlite3.connect(tmp_path / "lab.sqlite3", isolation_level=None, check_same_thread=False)
    other.execute("BEGIN IMMEDIATE")
    releaser = threading.Timer(0.3, lambda: other.execute("COMMIT"))
    releaser.start()
    waiting = Database(f"sqlite:///{tmp_path / 'lab.sqlite3'}")
    started = time.perf_counter()
    with waiting.write() as session:
        session.execute(text("UPDATE users SET role = role"))
    assert time.perf_counter() - started >= 0.25
    releaser.join()
    other.close()
    waiting.close()


def test_write_transactions_begin_immediate_on_sqlite(tmp_path: Path) -> None:
    db = Database(f"sqlite:///{tmp_path / 'lab.sqlite3'}")
    db.upgrade()
    statements: list[str] = []
    event.listen(
        db.engine,
        "before_cursor_execute",
        lambda conn, cursor, statement, *rest: statements.append(statement),
    )
    with db.write() as session:
        session.execute(text("SELECT 1"))
    with db.read() as session:
        session.execute(text("SELECT 1"))
    db.close()
    begins = [s for s in statements if s.startswith("BEGIN")]
    assert begins == ["BEGIN IMMEDIATE", "BEGIN"]


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("postgresql://u@h/db", "postgresql+psycopg://u@h/db"),
        ("postgres://u:pw@h:5433/db", "postgresql+psycopg://u:pw@h:5433/db"),
        ("postgresql+psycopg://u@h/db", "postgresql+psycopg://u@h/db"),
        ("sqlite:////srv/lab.sqlite3", "sqlite:////srv/lab.sqlite3"),
    ],
)
def test_database_urls_are_normalised(url: str, expected: str) -> None:
    assert normalize_database_url(url) == expected


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("mysql://u@h/db", "'mysql' is not supported"),
        ("postgresql+psycopg2://u@h/db", "not supported"),
        ("not a url", "not understood"),
    ],
)
def test_unsupported_databases_are_refused_with_a_clear_message(url: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        normalize_database_url(url)


def test_an_unreachable_database_is_a_one_line_error() -> None:
    db = Database("postgresql://nobody@127.0.0.1:1/none")
    with pytest.raises(ConfigError, match=r"cannot open the database .*127\.0\.0\.1.*refused"):
        db.upgrade()
    db.close()


@pytest.mark.postgres
def test_a_connection_still_in_use_at_close_is_closed_when_it_comes_back(
    postgres_url: str,
) -> None:
    # A run's thread may hold a connection while the lab closes the database; it
    # must be closed when returned, not left to the garbage collector.
    db = Database(postgres_url, pool_size=1, max_overflow=0)
    connection = db.engine.connect()
    raw = connection.connection.dbapi_connection
    db.close()
    assert raw is not None
    assert not raw.closed
    connection.close()
    assert raw.closed
