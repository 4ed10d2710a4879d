"""Removing a person: no table keeps a personal field of theirs, runs kept or deleted."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import String, Text, select
from sqlalchemy.orm import Session

from thermolab.cli import main
from thermolab.errors import ConflictError
from thermolab.lab.accounts.personal_data import forget_person
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.models import Base, Run
from thermolab.lab.http.app import create_app
from thermolab.lab.service import Lab

from .conftest import PASSWORD, LabFactory
from .test_runs import lab_request, person, twin_lab


def _texts(lab: Lab) -> list[tuple[str, str, str]]:
    """Every text value of every table: (table, column, value)."""
    found = []
    with lab.db.read() as session:
        for table in Base.metadata.sorted_tables:
            columns = [c for c in table.columns if isinstance(c.type, String | Text)]
            if not columns:
                continue
            for row in session.execute(select(*columns)):
                found += [(table.name, c.name, v) for c, v in zip(columns, row, strict=True) if v]
    return found


def _used_lab(make_lab: LabFactory) -> tuple[Lab, dict[str, str]]:
    """A lab where ana (with a display name) has run twice, logged in and made a token."""
    lab = twin_lab(make_lab)
    info = lab.users.add("ana", PASSWORD, "student", "Ana Beatriz Souza")
    ana, tina = Principal(info.id, info.username, info.role), person(lab, "tina", "teacher")
    for _ in range(2):
        lab.access.request_control("twin", ana)
        lab.runs.start("twin", ana, lab_request(samples=20))
        lab.runs.wait("twin", timeout=30)
        lab.access.release("twin", ana)
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        client.post(
            "/api/session",
            json={"username": "ana", "password": PASSWORD},
            headers={"user-agent": "Firefox/ana-laptop"},
        )
        client.post("/api/tokens", json={"name": "ana's notebook", "readOnly": True})
    assert tina.username == "tina"
    personal = {
        "username": "ana",
        "display name": "Ana Beatriz Souza",
        "agent": "Firefox/ana-laptop",
        "token": "ana's notebook",
    }
    assert any(v == "Firefox/ana-laptop" for _, _, v in _texts(lab))  # the scan sees it
    return lab, personal


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
@pytest.mark.parametrize("runs", ["keep", "delete"])
def test_no_table_keeps_a_personal_field_of_a_removed_person(
    make_lab: LabFactory, runs: str
) -> None:
    lab, personal = _used_lab(make_lab)
    with lab.db.read() as session:
        ana_runs = list(session.scalars(select(Run.id).order_by(Run.id)))
    pseudonym = forget_person(lab.db, "ANA", runs, "$argon2id$unknown")  # type: ignore[arg-type]
    left = [(t, c, v) for t, c, v in _texts(lab) if any(p in v for p in personal.values())]
    assert left == []
    with lab.db.read() as session:
        kept = list(session.scalars(select(Run.id).order_by(Run.id)))
    assert kept == (ana_runs if runs == "keep" else [])
    if runs == "keep":
        assert ("users", "username", pseudonym) in _texts(lab)
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        login = client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        assert login.status_code == 401


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_a_person_at_the_controls_is_removed_when_done(
    make_lab: LabFactory, capsys: pytest.CaptureFixture[str]
) -> None:
    lab = twin_lab(make_lab)
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    with pytest.raises(ConflictError, match="at a rig's controls or waiting"):
        forget_person(lab.db, "ana", "keep", "x")
    lab.access.release("twin", ana)
    url = lab.config.database
    assert main(["user", "forget", "ana", "--runs", "delete", "--database-url", url]) == 0
    assert capsys.readouterr().out.strip() == "forgot 'ana': their runs deleted"
    assert main(["user", "forget", "ana", "--runs", "keep", "--database-url", url]) == 1
    # The command line's removal is in the audit log too, naming the operator's shell.
    [entry] = lab.audit.list(action="account.forgotten")
    assert (entry.actor, entry.detail) == ("(command line)", {"runs": "delete"})
    assert entry.target.startswith("removed-")


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_a_removal_whose_audit_entry_cannot_be_written_removes_nobody(
    make_lab: LabFactory,
) -> None:
    """The removal and its entry in the audit log are one transaction: nobody leaves
    unlogged (they were two, and a failed entry left a removal no one could trace)."""
    lab = twin_lab(make_lab)
    person(lab, "ana")
    written = lab.audit.forgotten("root")

    def full_disk(session: Session, pseudonym: str) -> None:
        written(session, pseudonym)
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        forget_person(lab.db, "ana", "keep", "x", audit=full_disk)
    assert lab.users.get("ana").username == "ana"
    assert lab.audit.list(action="account.forgotten") == []
    pseudonym = forget_person(lab.db, "ana", "keep", "x", audit=lab.audit.forgotten("root"))
    [entry] = lab.audit.list(action="account.forgotten")
    assert (entry.actor, entry.target) == ("root", pseudonym)


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_an_administrator_forgets_a_student_through_the_api(
    lab: Lab, app_client: Callable[..., TestClient]
) -> None:
    for name, role in (("ana", "student"), ("ben", "student"), ("tina", "teacher")):
        lab.users.add(name, PASSWORD, role)
    lab.users.add("root", PASSWORD, "teacher", admin=True)
    ben, tina, root = app_client("ben"), app_client("tina"), app_client("root")
    body = {"runs": "keep"}
    assert ben.post("/api/users/ana/forget", json=body).status_code == 403
    # A person may be in several courses: removing one is an administrator's act.
    assert tina.post("/api/users/ana/forget", json=body).status_code == 403
    assert root.post("/api/users/root/forget", json=body).status_code == 403
    assert root.post("/api/users/ana/forget", json={"runs": "maybe"}).status_code == 422
    answer = root.post("/api/users/ana/forget", json=body)
    assert answer.status_code == 200, answer.text
    pseudonym = answer.json()["pseudonym"]
    assert pseudonym.startswith("removed-")
    assert "ana" not in [u["username"] for u in root.get("/api/users").json()]
    logged = root.get("/api/audit").json()
    entries = logged["entries"] if isinstance(logged, dict) else logged
    assert any(e["action"] == "account.forgotten" and e["target"] == pseudonym for e in entries)
    assert root.post("/api/users/ana/forget", json=body).status_code == 404
