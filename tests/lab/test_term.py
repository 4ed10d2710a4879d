"""The end of a term and the next: close, copy, remove last term's students (SQLite, PostgreSQL).

The lab's clock starts on 2026-01-01 00:00 UTC (``ManualClock``); the term's
bookings and deadlines are in March, the next term's 26 weeks later.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select, update

from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.models import Course, Run, User
from thermolab.lab.http.app import create_app
from thermolab.lab.runs.request import RunRequest

from .conftest import PASSWORD, LabFactory
from .test_runs import twin_lab

MARCH = datetime(2026, 3, 2, 14, 0, tzinfo=UTC)  # a Monday
NEXT_TERM = 182  # days: 26 weeks, so Mondays stay Mondays


def _assignment(deadline: datetime) -> dict[str, Any]:
    return {
        "title": "Step response",
        "rig": "twin",
        "methods": ["lsm"],
        "deadline": deadline.isoformat(),
    }


def _slot(start: datetime, course: str = "ctrl1") -> dict[str, Any]:
    return {
        "course": course,
        "rigs": ["twin"],
        "startsAt": start.isoformat(),
        "endsAt": (start + timedelta(hours=2)).isoformat(),
        "note": "turma A",
    }


Login = Callable[[str], TestClient]


@pytest.fixture
def world(make_lab: LabFactory) -> Any:
    """tina's course ``ctrl1``: ana and beto, its rigs and limits, an assignment, three bookings.

    ana made a run (her turn over); beto is also in otto's open course ``ctrl2``.
    """
    lab = twin_lab(make_lab)
    add = lab.users.add
    people = {
        name: add(name, PASSWORD, role, admin=name == "root")
        for name, role in (
            ("root", "teacher"),
            ("tina", "teacher"),
            ("otto", "teacher"),
            ("ana", "student"),
            ("beto", "student"),
        )
    }
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    clients: list[TestClient] = []

    def login(name: str) -> TestClient:
        client = TestClient(app)
        clients.append(client)
        assert client.post("/api/session", json={"username": name, "password": PASSWORD}).is_success
        return client

    tina = login("tina")
    assert tina.post("/api/courses", json={"name": "ctrl1", "title": "Controle I"}).is_success
    roster = b"username,display_name\nana,Ana Lima\nbeto,Beto Souza\n"
    assert tina.put("/api/courses/ctrl1/roster", content=roster).is_success
    assert tina.put("/api/courses/ctrl1/rigs", json={"rigs": ["twin", "other"]}).is_success
    limits = {"version": 0, "values": {"control_time_limit": 900}}
    assert tina.put("/api/courses/ctrl1/settings", json=limits).is_success
    made = tina.post("/api/courses/ctrl1/assignments", json=_assignment(MARCH + timedelta(days=7)))
    assert made.status_code == 201, made.text
    for week in range(3):
        booked = tina.post("/api/bookings", json=_slot(MARCH + timedelta(weeks=week)))
        assert booked.status_code == 201, booked.text
    lab.courses.create("ctrl2", "Controle II", "otto")
    lab.courses.import_class_list("ctrl2", b"username,display_name\nbeto,Beto Souza\n")
    ana = Principal(people["ana"].id, "ana", people["ana"].role)
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, RunRequest(dt=1.0, samples=20, signal="step:0:10@5"))
    lab.runs.wait("twin", timeout=60)
    lab.access.release("twin", ana)
    yield {"lab": lab, "login": login, "tina": tina, "assignment": made.json()["id"], "run": run.id}
    for client in clients:
        client.close()


def test_a_closed_course_is_read_and_exported_never_changed(world: Any) -> None:
    lab, login, tina = world["lab"], world["login"], world["tina"]
    ana = login("ana")
    # A slot under way stays when the course closes (those to come are cancelled).
    under_way = tina.post("/api/bookings", json=_slot(lab.clock.now() - timedelta(minutes=30)))
    assert under_way.status_code == 201, under_way.text
    closed = tina.post("/api/courses/ctrl1/close")
    assert closed.status_code == 200, closed.text
    assert closed.json()["closedBy"] == "tina"
    assert closed.json()["closedAt"].startswith("2026-01-01")
    refusals = [
        tina.put("/api/courses/ctrl1/roster", content=b"username,display_name\ncarla,C\n"),
        tina.post("/api/courses/ctrl1/enrol-code"),
        tina.put("/api/courses/ctrl1/rigs", json={"rigs": []}),
        tina.put("/api/courses/ctrl1/settings", json={"version": 1, "values": {}}),
        tina.post("/api/courses/ctrl1/assignments", json=_assignment(MARCH)),
        tina.put(f"/api/assignments/{world['assignment']}", json=_assignment(MARCH)),
        tina.post("/api/bookings", json=_slot(MARCH + timedelta(weeks=5))),
        ana.post(
            f"/api/assignments/{world['assignment']}/submissions",
            json={"runId": world["run"], "K": 0.14, "tau": 250.0},
        ),
        tina.post("/api/courses/ctrl1/close"),
    ]
    refusals.append(tina.delete(f"/api/bookings/{under_way.json()['id']}"))
    code = lab.courses.get("ctrl1").enrol_code
    refusals.append(
        login("root").post(
            "/api/enrol",
            json={"code": code, "username": "carla", "displayName": "Carla", "password": PASSWORD},
        )
    )
    for answer in refusals:
        assert answer.status_code == 409, answer.text
        assert answer.json()["code"] == "course_closed", answer.text
    # In the reader's language, with the precise reason beside it.
    pt = tina.post("/api/courses/ctrl1/enrol-code", headers={"Accept-Language": "pt-BR"})
    sentence = "Esta disciplina está encerrada: pode ser consultada, mas não alterada."
    assert pt.json()["message"] == sentence
    assert "closed on 2026-01-01 by tina" in pt.json()["detail"]
    # Reads and exports go on.
    assert tina.get("/api/courses/ctrl1").is_success
    assert tina.get("/api/courses/ctrl1/grades.csv").is_success
    assert ana.get(f"/api/assignments/{world['assignment']}").is_success
    assert ana.get("/api/me/export").is_success
    # Its teacher may not reopen it; an administrator may, and then it changes again.
    assert tina.post("/api/courses/ctrl1/reopen").status_code == 403
    root = login("root")
    reopened = root.post("/api/courses/ctrl1/reopen")
    assert reopened.status_code == 200, reopened.text
    assert reopened.json()["closedAt"] is None
    assert tina.post("/api/courses/ctrl1/enrol-code").is_success
    assert root.post("/api/courses/ctrl1/reopen").status_code == 409
    actions = {e.action for e in lab.audit.list()}
    assert {"course.closed", "course.reopened"} <= actions


def test_a_course_copies_to_the_next_term_without_its_people(world: Any) -> None:
    lab, login = world["lab"], world["login"]
    # The term is over (its slots past, so the close cancels none); a closed course copies.
    lab.clock.advance((MARCH + timedelta(weeks=4) - lab.clock.now()).total_seconds())
    tina = login("tina")  # the fixture's login has expired meanwhile
    closed = tina.post("/api/courses/ctrl1/close")
    assert closed.status_code == 200, closed.text
    assert closed.json()["releasedBookings"] == 0
    otto = login("otto")
    copied = otto.post("/api/courses/ctrl1/copy", json={"name": "ctrl1-2026-2", "shiftDays": 182})
    assert copied.status_code == 403  # not otto's course
    copied = tina.post(
        "/api/courses/ctrl1/copy", json={"name": "ctrl1-2026-2", "starts": "2026-08-31"}
    )
    assert copied.status_code == 201, copied.text
    report = copied.json()
    assert report["shiftDays"] == NEXT_TERM
    assert (report["assignments"], report["bookings"], report["skippedBookings"]) == (1, 3, [])
    course = report["course"]
    assert course["closedAt"] is None
    assert course["rigs"] == ["other", "twin"]
    assert [(m["username"], m["role"]) for m in course["members"]] == [("tina", "teacher")]
    assert course["enrolCode"] != lab.courses.get("ctrl1").enrol_code
    limits = tina.get("/api/courses/ctrl1-2026-2/settings").json()
    overridden = {s["name"]: s["value"] for s in limits["settings"] if s["overridden"]}
    assert overridden == {"control_time_limit": 900}
    # The assignment, as a draft with its deadline moved; no hand-ins, no marks.
    drafts = [a for a in tina.get("/api/assignments").json() if a["course"] == "ctrl1-2026-2"]
    assert [(a["title"], a["draft"], a["mine"]) for a in drafts] == [("Step response", True, [])]
    deadline = datetime.fromisoformat(drafts[0]["deadline"])
    assert deadline == MARCH + timedelta(days=7 + NEXT_TERM)
    assert tina.get("/api/courses/ctrl1-2026-2/grades.csv").text.count("\n") <= 1
    # The booking pattern: the same weekday and hour, 26 weeks later.
    window = {"from": "2026-08-01T00:00:00+00:00", "to": "2026-10-01T00:00:00+00:00"}
    slots = tina.get("/api/bookings", params=window).json()
    starts = sorted(datetime.fromisoformat(s["startsAt"]) for s in slots)
    assert starts == [MARCH + timedelta(days=NEXT_TERM, weeks=w) for w in range(3)]
    assert all(s["course"] == "ctrl1-2026-2" and s["note"] == "turma A" for s in slots)
    # A name clash is a 409; neither way to date, or both, a 422.
    again = tina.post("/api/courses/ctrl1/copy", json={"name": "ctrl1-2026-2", "shiftDays": 1})
    assert (again.status_code, again.json()["code"]) == (409, "course_name_taken")
    for body in ({"name": "x"}, {"name": "x", "shiftDays": 1, "starts": "2026-08-31"}):
        assert tina.post("/api/courses/ctrl1/copy", json=body).status_code == 422
    bad = tina.post("/api/courses/ctrl1/copy", json={"name": "no spaces", "shiftDays": 1})
    assert (bad.status_code, bad.json()["code"]) == (422, "invalid_parameter")
    # A student of the new course does not see the draft until it is published.
    new_roster = b"username,display_name\nbeto,B\n"
    assert tina.put("/api/courses/ctrl1-2026-2/roster", content=new_roster).is_success
    beto = login("beto")
    assert [a for a in beto.get("/api/assignments").json() if a["course"] == "ctrl1-2026-2"] == []
    assert beto.get(f"/api/assignments/{drafts[0]['id']}").status_code == 403
    published = tina.post(f"/api/assignments/{drafts[0]['id']}/publish")
    assert published.status_code == 200, published.text
    assert published.json()["draft"] is False
    seen = [a["id"] for a in beto.get("/api/assignments").json() if a["course"] == "ctrl1-2026-2"]
    assert seen == [drafts[0]["id"]]
    # A copy over a busy week leaves the clashing slots out and says why.
    shifted = tina.post("/api/courses/ctrl1/copy", json={"name": "clash", "shiftDays": NEXT_TERM})
    assert shifted.status_code == 201, shifted.text
    assert shifted.json()["bookings"] == 0
    assert len(shifted.json()["skippedBookings"]) == 3
    assert "overlaps" in shifted.json()["skippedBookings"][0]["reason"]


def test_last_terms_students_are_removed_in_one_action(world: Any) -> None:
    lab, login, tina = world["lab"], world["login"], world["tina"]
    root = login("root")
    # Not while the course is open, and never by its teacher.
    assert root.get("/api/courses/ctrl1/leavers").status_code == 409
    assert tina.post("/api/courses/ctrl1/close").is_success
    assert tina.get("/api/courses/ctrl1/leavers").status_code == 403
    listed = root.get("/api/courses/ctrl1/leavers")
    assert listed.status_code == 200, listed.text
    # beto is still in ctrl2, which is open: he stays.
    assert listed.json() == [{"username": "ana", "displayName": "Ana Lima"}]
    stale = root.post(
        "/api/courses/ctrl1/purge-students", json={"students": ["ana", "beto"], "runs": "keep"}
    )
    assert (stale.status_code, stale.json()["code"]) == (409, "leavers_changed")
    assert lab.users.get("ana").username == "ana"  # nobody was removed
    purged = root.post(
        "/api/courses/ctrl1/purge-students", json={"students": ["ana"], "runs": "keep"}
    )
    assert purged.status_code == 200, purged.text
    [pseudonym] = purged.json()["removed"]
    assert pseudonym.startswith("removed-")
    assert purged.json()["skipped"] == {}
    with lab.db.read() as session:
        names = set(session.scalars(select(User.username)))
        kept = session.scalar(select(func.count()).select_from(Run).where(Run.id == world["run"]))
    assert "ana" not in names
    assert {"beto", pseudonym} <= names
    assert kept == 1  # her run stays under the pseudonym, for the class's statistics
    assert root.get("/api/courses/ctrl1/leavers").json() == []
    entries = root.get("/api/audit").json()
    purges = [e for e in entries if e["action"] == "course.students_purged"]
    assert [p["detail"]["removed"] for p in purges] == [[pseudonym]]
    assert any(e["action"] == "account.forgotten" and e["target"] == pseudonym for e in entries)
    assert not any(e["target"] == "ana" for e in entries)


def test_removal_with_their_runs_and_a_closing_teachers_name_replaced(world: Any) -> None:
    lab, login, tina = world["lab"], world["login"], world["tina"]
    root = login("root")
    assert tina.post("/api/courses/ctrl1/close").is_success
    purged = root.post(
        "/api/courses/ctrl1/purge-students", json={"students": ["ana"], "runs": "delete"}
    )
    assert purged.status_code == 200, purged.text
    with lab.db.read() as session:
        assert session.get(Run, world["run"]) is None  # her run went with her
    # The teacher who closed the course is later removed: "closed by" is their pseudonym.
    tina.close()
    forgotten = root.post("/api/users/tina/forget", json={"runs": "keep"})
    assert forgotten.status_code == 200, forgotten.text
    closed = root.get("/api/courses/ctrl1").json()
    assert closed["closedBy"] == forgotten.json()["pseudonym"]
    # Bad bodies are 422 with a reason, never a 500.
    for body in ({"students": ["ana"]}, {"students": "ana", "runs": "keep"}, {"runs": "both"}):
        answer = root.post("/api/courses/ctrl1/purge-students", json=body)
        assert (answer.status_code, answer.json()["code"]) == (422, "invalid_request")
    assert root.post("/api/courses/nope/close").status_code == 404


def test_closing_a_course_frees_the_rigs_of_its_bookings_to_come(world: Any) -> None:
    lab, login, tina = world["lab"], world["login"], world["tina"]
    otto, root = login("otto"), login("root")
    # A slot under way when the course closes (the clock is at 2026-01-01 00:00).
    now = lab.clock.now()
    under_way = tina.post("/api/bookings", json=_slot(now - timedelta(minutes=30)))
    assert under_way.status_code == 201, under_way.text
    # Before the close, ctrl1's March slots keep the twin from otto's course.
    before = otto.post("/api/bookings", json=_slot(MARCH, course="ctrl2"))
    assert (before.status_code, before.json()["code"]) == (409, "booking_clash")
    closed = tina.post("/api/courses/ctrl1/close")
    assert closed.status_code == 200, closed.text
    assert closed.json()["releasedBookings"] == 3

    # Its three March slots are gone; the one under way stays to its end.
    def calendar() -> list[tuple[str, str]]:
        slots = []
        for start in (now - timedelta(days=1), MARCH - timedelta(days=7)):
            window = {"from": start.isoformat(), "to": (start + timedelta(days=60)).isoformat()}
            answer = tina.get("/api/bookings", params=window)
            assert answer.status_code == 200, answer.text
            slots += [(b["course"], b["startsAt"]) for b in answer.json()]
        return sorted(set(slots), key=lambda slot: slot[1])

    assert calendar() == [("ctrl1", under_way.json()["startsAt"])]
    # Another course books the freed slot; a reopen does not bring the old ones back.
    after = otto.post("/api/bookings", json=_slot(MARCH, course="ctrl2"))
    assert after.status_code == 201, after.text
    assert root.post("/api/courses/ctrl1/reopen").is_success
    assert calendar() == [
        ("ctrl1", under_way.json()["startsAt"]),
        ("ctrl2", after.json()["startsAt"]),
    ]
    [entry] = [e for e in root.get("/api/audit").json() if e["action"] == "course.closed"]
    assert entry["detail"] == {"released_bookings": 3}


def test_a_booking_made_while_the_course_closes_waits_for_the_close_and_is_refused(
    world: Any,
) -> None:
    lab, tina = world["lab"], world["tina"]
    answers: list[Any] = []
    later = MARCH + timedelta(weeks=8)
    booking = threading.Thread(
        target=lambda: answers.append(tina.post("/api/bookings", json=_slot(later)))
    )
    # A close under way: the course's row changed, not yet committed.
    with lab.db.write() as session:
        session.execute(
            update(Course)
            .where(Course.name == "ctrl1")
            .values(closed_at=lab.clock.now(), closed_by="root")
        )
        session.flush()
        booking.start()
        booking.join(timeout=0.5)
        assert booking.is_alive()  # the booking waits for the close
    booking.join(timeout=60)
    [answer] = answers
    assert (answer.status_code, answer.json()["code"]) == (409, "course_closed"), answer.text
