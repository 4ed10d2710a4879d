"""The audit log and the administrators' migration (issue #25).

Privileged actions through the API leave one row each (who, what, on whom,
when, from where) and never a password; administrators read them as JSON and
as formula-safe CSV, nobody else can. Migration 0018 makes the oldest teacher
of an existing lab its administrator.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import alembic.command
import pytest
from alembic.config import Config
from fastapi.testclient import TestClient
from sqlalchemy import text

from thermolab.lab.db import MIGRATIONS_DIR, Database
from thermolab.lab.service import Lab

from .conftest import PASSWORD

Client = Callable[..., TestClient]


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


def test_privileged_actions_are_logged_and_only_administrators_read_them(
    lab: Lab, app_client: Client
) -> None:
    lab.users.add("root", PASSWORD, "teacher", admin=True)
    lab.users.add("tina", PASSWORD, "teacher")
    root, tina = app_client("root"), app_client("tina")
    assert tina.post("/api/courses", json={"name": "ctrl1", "title": "C"}).status_code == 201
    roster = tina.put(
        "/api/courses/ctrl1/roster",
        content=b"username,display_name\nana,Ana\n",
        headers={"content-type": "text/csv"},
    )
    assert roster.status_code == 200, roster.text
    temporary = roster.json()["created"]["ana"]
    reset = tina.post("/api/users/ana/password-reset", json={"currentPassword": PASSWORD})
    assert reset.status_code == 200, reset.text
    settings = {"version": 1, "values": {"control_time_limit": 120}}
    assert root.put("/api/rigs/twin/settings", json=settings).status_code == 200
    assert tina.get("/api/audit").status_code == 403
    assert root.put("/api/users/tina/admin", json={"admin": True}).status_code == 200
    new = {"username": "ben", "password": "a long ben secret", "role": "student"}
    assert root.post("/api/users", json=new).status_code == 201

    assert tina.get("/api/audit").status_code == 200  # an administrator now
    rows = root.get("/api/audit").json()
    seen = [(r["actor"], r["action"], r["target"]) for r in reversed(rows)]
    assert seen == [
        ("tina", "course.created", "ctrl1"),
        ("tina", "course.roster", "ctrl1"),
        ("tina", "password.reset", "ana"),
        ("root", "rig.settings", "twin"),
        ("root", "account.admin", "tina"),
        ("root", "account.created", "ben"),
    ]
    assert all(r["address"] == "testclient" for r in rows)
    assert all(datetime.fromisoformat(r["at"]).tzinfo is not None for r in rows)
    body = root.get("/api/audit").text + root.get("/api/audit.csv").text
    for secret in (PASSWORD, temporary, reset.json()["temporaryPassword"], "a long ben secret"):
        assert secret not in body
    only = root.get("/api/audit", params={"action": "password.reset"}).json()
    assert [r["target"] for r in only] == ["ana"]

    exported = root.get("/api/audit.csv")
    assert exported.headers["content-type"].startswith("text/csv")
    table = list(csv.reader(io.StringIO(exported.text)))
    assert table[0] == ["id", "at", "actor", "action", "target", "address", "detail"]
    assert len(table) == 1 + len(rows)
    student = app_client()
    login = {"username": "ben", "password": "a long ben secret"}
    assert student.post("/api/session", json=login).status_code == 200
    assert student.get("/api/audit").status_code == 403
    assert student.get("/api/audit.csv").status_code == 403


def test_a_cell_a_spreadsheet_would_run_is_quoted(lab: Lab) -> None:
    from thermolab.lab.audit.log import AuditAction, AuditLog

    lab.audit.record("=evil", AuditAction.ROSTER_CHANGED, "+cmd", address="@x")
    [row] = list(csv.reader(io.StringIO(AuditLog.to_csv(lab.audit.list()))))[1:]
    assert row[2:6] == ["'=evil", "course.roster", "'+cmd", "'@x"]


def test_the_migration_makes_the_oldest_teacher_the_administrator(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'old.sqlite3'}"
    db = Database(url, pool_size=1, max_overflow=0)
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    with db.engine.begin() as connection:
        config.attributes["connection"] = connection
        alembic.command.upgrade(config, "0017")
    with db.engine.begin() as connection:
        for number, (name, role) in enumerate(
            [("ana", "student"), ("first", "teacher"), ("second", "teacher")]
        ):
            connection.execute(
                text(
                    "INSERT INTO users (username, role, password_hash, created_at, "
                    "password_changed_at, must_change_password) "
                    "VALUES (:name, :role, 'x', :at, :at, false)"
                ),
                {"name": name, "role": role, "at": datetime(2026, 1, 1 + number, tzinfo=UTC)},
            )
    db.upgrade()
    with db.engine.connect() as connection:
        admins = connection.execute(
            text("SELECT username FROM users WHERE admin ORDER BY username")
        ).scalars()
        assert list(admins) == ["first"]
    db.close()
