"""Courses and people: class lists, self-enrolment, password resets (SQLite and PostgreSQL)."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from thermolab.errors import CLASS_LIST_PROBLEMS, AccessDeniedError, ClassListError
from thermolab.lab.db.models import CourseMember, User
from thermolab.lab.error_messages import translate
from thermolab.lab.service import Lab

from .conftest import PASSWORD

Clients = Callable[..., TestClient]
GOOD_LIST = "username,display_name\nJoão.Silva,João da Silva\nmaria,Maria Álvares\n"


def _counts(lab: Lab) -> tuple[int, int]:
    with lab.db.read() as session:
        users = session.scalar(select(func.count()).select_from(User)) or 0
        members = session.scalar(select(func.count()).select_from(CourseMember)) or 0
    return users, members


@pytest.fixture
def teacher(lab: Lab, app_client: Clients) -> TestClient:
    lab.users.add("tina", PASSWORD, "teacher")
    client = app_client("tina")
    created = client.post("/api/courses", json={"name": "ctrl1", "title": "Controle I"})
    assert created.status_code == 201, created.text
    return client


def test_a_class_list_creates_students_and_a_reupload_updates_them(
    lab: Lab, teacher: TestClient, app_client: Clients
) -> None:
    first = teacher.put("/api/courses/ctrl1/roster", content=GOOD_LIST.encode())
    assert first.status_code == 200, first.text
    report = first.json()
    assert sorted(report["created"]) == ["joao.silva", "maria"]
    # Each new student logs in with the one-time password and must change it first.
    student = app_client()
    login = student.post(
        "/api/session", json={"username": "JOAO.SILVA", "password": report["created"]["joao.silva"]}
    )
    assert login.status_code == 200
    assert login.json()["mustChangePassword"] is True
    refused = student.get("/api/rigs")
    assert refused.status_code == 403
    assert refused.json()["code"] == "password_change_required"
    changed = student.put(
        "/api/users/joao.silva/password",
        json={"password": "my own long secret", "currentPassword": report["created"]["joao.silva"]},
    )
    assert changed.status_code == 204, changed.text
    assert student.get("/api/rigs").status_code == 200

    # Again, with one name re-spelt (case, accents, display name changed) and one new: no duplicate.
    again = "username;name\nJOAO.SILVA;João Silva Neto\nMaria;Maria Álvares\nana;Ana\n"
    second = teacher.put("/api/courses/ctrl1/roster", content=again.encode("utf-8-sig"))
    assert second.status_code == 200, second.text
    assert list(second.json()["created"]) == ["ana"]
    assert second.json()["updated"] == ["joao.silva"]
    assert second.json()["unchanged"] == ["maria"]
    assert _counts(lab) == (4, 4)  # tina + 3 students, each once in the course
    roster = teacher.get("/api/courses/ctrl1").json()
    assert [(m["username"], m["displayName"], m["role"]) for m in roster["members"]] == [
        ("tina", None, "teacher"),
        ("ana", "Ana", "student"),
        ("joao.silva", "João Silva Neto", "student"),
        ("maria", "Maria Álvares", "student"),
    ]
    # The student who changed the password keeps it: a re-upload never resets it.
    assert lab.users.verify("joao.silva", "my own long secret").username == "joao.silva"


@pytest.mark.parametrize(
    ("data", "lines", "reason"),
    [
        (b"login,turma\nana,A\n", [1], "must have one login column"),
        (b"username,display_name,email\nana,Ana,a@x\n", [1], "must have one login column"),
        (b"username,display_name\nana,Ana\nbia,Bia,extra\nana,Ana B\n", [3, 4], "cells"),
        (b"username,display_name\nana,Ana\nANA,Ana\n", [3], "already on line 2"),
        (b"username,display_name\nana,Ana\nJo\x81o,Jo\x81o\n", [3], "not text in UTF-8"),
        (b"PK\x03\x04\x14\x00\x06\x00", [1], "spreadsheet workbook"),
        (b"username,display_name\na b,Ana\nbia,<script>\n", [2, 3], "not valid"),
        (b"username,display_name\n", [2], "no student"),
        (b"", [1], "empty"),
        (b'username,display_name\nana,"Ana"x\n', [2], "not readable as CSV"),
        (b'username,name\r\nana,"Ana\r\nB"\r\nbia,\r\n', [4], "display name '' is not valid"),
        (b"username,display_name\ntina,Tina\n", [2], "teacher's account"),
    ],
)
def test_a_malformed_class_list_reports_each_bad_line_and_changes_nothing(
    lab: Lab, teacher: TestClient, data: bytes, lines: list[int], reason: str
) -> None:
    before = _counts(lab)
    answer = teacher.put(
        "/api/courses/ctrl1/roster", content=data, headers={"Accept-Language": "pt-BR"}
    )
    assert answer.status_code == 422, answer.text
    body = answer.json()
    assert body["code"] == "class_list_invalid"
    assert body["message"] == "A lista da turma tem linhas com erro; nada foi alterado."
    assert [int(e["loc"][1]) for e in body["errors"]] == lines
    assert any(reason in e["msg"] for e in body["errors"])
    # Each problem has a stable code, its values and its sentence in the reader's language.
    for problem in body["errors"]:
        assert problem["type"] in CLASS_LIST_PROBLEMS
        english = CLASS_LIST_PROBLEMS[problem["type"]].format(**problem["params"])
        assert problem["msg"] == english
        assert problem["message"] == translate(
            CLASS_LIST_PROBLEMS[problem["type"]], "pt-BR"
        ).format(**problem["params"])
        assert problem["message"] != english
    assert _counts(lab) == before


def test_a_list_with_one_bad_line_adds_none_of_the_good_ones(lab: Lab) -> None:
    lab.users.add("tina", PASSWORD, "teacher")
    lab.courses.create("ctrl1", "Controle I", "tina")
    with pytest.raises(ClassListError, match="line 4"):
        lab.courses.import_class_list("ctrl1", b"username,name\nana,Ana\nbia,Bia\n-x,X\n")
    assert [u.username for u in lab.users.list()] == ["tina"]
    lab.users.add("rui", PASSWORD, "student")
    with pytest.raises(AccessDeniedError, match="'rui' is not a teacher's account"):
        lab.courses.create("ctrl2", "Controle II", "rui")


def test_a_student_enrols_with_the_code_and_a_rotated_code_stops_working(
    lab: Lab, teacher: TestClient, app_client: Clients
) -> None:
    code = teacher.get("/api/courses/ctrl1").json()["enrolCode"]
    public = app_client()
    body = {"code": code.lower(), "username": "Bia", "displayName": "Beatriz Gonçalves"}
    weak = public.post("/api/enrol", json={**body, "password": "password1234"})
    assert weak.status_code == 422
    assert "breached" in weak.json()["detail"]
    done = public.post("/api/enrol", json={**body, "password": "a long bia secret"})
    assert done.status_code == 201, done.text
    assert done.json() == {"username": "bia", "displayName": "Beatriz Gonçalves"}
    twice = public.post("/api/enrol", json={**body, "password": "a long bia secret"})
    assert twice.status_code == 409
    login = public.post("/api/session", json={"username": "bia", "password": "a long bia secret"})
    assert login.status_code == 200
    assert login.json()["mustChangePassword"] is False
    members = [m["username"] for m in teacher.get("/api/courses/ctrl1").json()["members"]]
    assert "bia" in members

    new_code = teacher.post("/api/courses/ctrl1/enrol-code").json()["enrolCode"]
    assert new_code != code
    stale = app_client().post(
        "/api/enrol",
        json={**body, "code": code, "username": "caio", "password": "a long caio secret"},
    )
    assert stale.status_code == 403
    assert stale.json()["code"] == "enrol_code_wrong"


def test_guessing_enrolment_codes_is_throttled(lab: Lab, app_client: Clients) -> None:
    public = app_client()
    body = {"username": "eve", "displayName": "Eve", "password": "a long eve secret"}
    statuses = [
        public.post("/api/enrol", json={**body, "code": "WRONGCODE1"}).status_code for _ in range(8)
    ]
    assert statuses[:5] == [403] * 5
    assert statuses[-1] == 429


def test_a_teacher_resets_a_students_password_after_reauthenticating(
    lab: Lab, teacher: TestClient, app_client: Clients
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    lab.courses.import_class_list("ctrl1", b"username,display_name\nana,Ana\n")
    ana = app_client("ana")
    wrong = teacher.post(
        "/api/users/ana/password-reset", json={"currentPassword": "not mine at all"}
    )
    assert wrong.status_code == 403
    assert (
        ana.post("/api/users/ana/password-reset", json={"currentPassword": PASSWORD}).status_code
        == 403
    )
    reset = teacher.post("/api/users/ANA/password-reset", json={"currentPassword": PASSWORD})
    assert reset.status_code == 200, reset.text
    temporary = reset.json()["temporaryPassword"]
    assert ana.get("/api/session").status_code == 401  # her logins ended
    fresh = app_client()
    assert (
        fresh.post("/api/session", json={"username": "ana", "password": PASSWORD}).status_code
        == 401
    )
    login = fresh.post("/api/session", json={"username": "ana", "password": temporary})
    assert login.json()["mustChangePassword"] is True
    assert fresh.get("/api/runs").json()["code"] == "password_change_required"
    tina_reset = teacher.post("/api/users/tina/password-reset", json={"currentPassword": PASSWORD})
    assert tina_reset.status_code == 403


def test_course_rigs_default_to_all_and_unknown_rigs_are_refused(teacher: TestClient) -> None:
    assert teacher.get("/api/courses/ctrl1").json()["rigs"] == []
    chosen = teacher.put("/api/courses/ctrl1/rigs", json={"rigs": ["twin"]})
    assert chosen.status_code == 200
    assert chosen.json()["rigs"] == ["twin"]
    unknown = teacher.put("/api/courses/ctrl1/rigs", json={"rigs": ["nope"]})
    assert unknown.status_code == 404
    assert "no rig called 'nope'" in unknown.json()["detail"]


def test_students_cannot_manage_courses_and_bad_names_are_4xx(
    lab: Lab, teacher: TestClient, app_client: Clients
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    ana = app_client("ana")
    assert ana.get("/api/courses").status_code == 403
    assert ana.put("/api/courses/ctrl1/roster", content=GOOD_LIST.encode()).status_code == 403
    assert teacher.post("/api/courses", json={"name": "ctrl1", "title": "x"}).status_code == 409
    bad = teacher.post("/api/courses", json={"name": "a b", "title": "x"})
    assert bad.status_code == 422
    assert bad.json()["code"] == "invalid_parameter"
    assert teacher.get("/api/courses/nope").status_code == 404
    assert [c["name"] for c in teacher.get("/api/courses").json()] == ["ctrl1"]


def test_a_student_may_ask_only_for_the_rigs_of_their_courses(
    lab: Lab, teacher: TestClient, app_client: Clients
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    lab.users.add("rui", PASSWORD, "student")  # in no course: every rig
    teacher.put("/api/courses/ctrl1/roster", content=b"username,name\nana,Ana\n")
    teacher.put("/api/courses/ctrl1/rigs", json={"rigs": ["other"]})
    ana = app_client("ana")
    refused = ana.post("/api/rigs/twin/control")
    assert refused.status_code == 403
    assert "do not use rig 'twin'" in refused.json()["detail"]
    assert ana.post("/api/rigs/other/control").status_code == 200
    assert app_client("rui").post("/api/rigs/twin/control").status_code == 200
    # Back to every rig: the course lists none.
    teacher.put("/api/courses/ctrl1/rigs", json={"rigs": []})
    ana.delete("/api/rigs/other/control")
    assert ana.post("/api/rigs/twin/control").status_code == 200
