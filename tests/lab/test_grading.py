"""A teacher's grading tools through the API (issue #24 item 7), on SQLite.

Marks overridden with a comment (the automatic mark kept beside it, in the
grades, the spreadsheet, the analytics and what the LMS is told), one
student's deadline extended, lab groups that hand in once for every member and
whose members read (only read) the group's runs.
The runs are real twin runs, identified again when handed in.
"""

from __future__ import annotations

import csv
import io
from datetime import datetime, timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from thermolab.lab.accounts.personal_data import forget_person
from thermolab.lab.accounts.users import Principal
from thermolab.lab.assignments import GradeRow
from thermolab.lab.clock import ManualClock
from thermolab.lab.service import Lab

from .conftest import PASSWORD
from .test_assignments import _assignment, _client, _run, school  # noqa: F401 - the fixture

# On SQLite alone: marking rules over the same store (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only


@pytest.fixture
def bench(school: Any) -> Any:  # noqa: F811 - the imported fixture
    """``school`` with students bea and cid in ctrl1, assistant tara, and one assignment."""
    lab: Lab = school["lab"]
    clients: list[TestClient] = []
    for name in ("bea", "cid", "tara"):
        made = lab.users.add(name, PASSWORD, "student")
        school[f"{name}_p"] = Principal(made.id, made.username, made.role)
    lab.courses.import_class_list("ctrl1", b"username,display_name\nana,-Ana\nbea,Bea\ncid,Cid\n")
    lab.assistants.add("ctrl1", "tara")
    for name in ("bea", "cid", "tara"):
        school[name] = _client(lab, clients, name)
    deadline = school["clock"].now() + timedelta(hours=1)
    body = _assignment(methods=["lsm"], settings={}, deadline=deadline.isoformat())
    school["assignment"] = school["tina"].post("/api/courses/ctrl1/assignments", json=body).json()
    school["deadline"] = deadline
    yield school
    for client in clients:
        client.close()


def _hand_in(client: TestClient, assignment_id: int, run_id: int, K: float = 0.1401) -> Any:
    answer = client.post(
        f"/api/assignments/{assignment_id}/submissions",
        json={"runId": run_id, "K": K, "tau": 250.0, "theta": 0.0},
    )
    assert answer.status_code == 201, answer.text
    return answer.json()


def _after(clock: ManualClock, seconds: float, clients: dict[str, TestClient]) -> None:
    """Move the clock on and log each client in again (its session idled out meanwhile)."""
    clock.advance(seconds)
    for name, client in clients.items():
        answer = client.post("/api/session", json={"username": name, "password": PASSWORD})
        assert answer.status_code == 200, answer.text


def _standings(client: TestClient, assignment_id: int) -> dict[str, Any]:
    answer = client.get(f"/api/assignments/{assignment_id}/standings")
    assert answer.status_code == 200, answer.text
    return {s["student"]: s for s in answer.json()}


def test_a_teacher_overrides_a_mark_with_a_comment_and_the_automatic_mark_stays(
    bench: Any,
) -> None:
    lab: Lab = bench["lab"]
    tina, ana, tara = bench["tina"], bench["ana"], bench["tara"]
    aid = bench["assignment"]["id"]
    heard: list[GradeRow] = []
    lab.assignments.on_marked(heard.append)
    automatic = _hand_in(ana, aid, _run(lab, bench["ana_p"]), K=0.2)["mark"]
    assert automatic == pytest.approx(10 * 4 / 6, abs=0.05)
    url = f"/api/assignments/{aid}/overrides/ana"

    refused = {
        "above the maximum": ({"mark": 10.5, "comment": "x"}, 422),
        "no comment": ({"mark": 8, "comment": ""}, 422),
        "blank comment": ({"mark": 8, "comment": "   "}, 422),
    }
    for what, (body, code) in refused.items():
        answer = tina.put(url, json=body)
        assert answer.status_code == code, (what, answer.text)
        assert "code" in answer.json()
    assert (
        tina.put(f"/api/assignments/{aid}/overrides/ben", json={"mark": 1, "comment": "x"}).json()[
            "code"
        ]
        == "not_found"
    )
    nothing = tina.put(f"/api/assignments/{aid}/overrides/bea", json={"mark": 1, "comment": "x"})
    assert (nothing.status_code, nothing.json()["code"]) == (409, "nothing_handed_in")
    assert "handed nothing in" in nothing.json()["detail"]
    # Assistants and students read; only the course's teachers override.
    assert tara.put(url, json={"mark": 8, "comment": "x"}).status_code == 403
    assert ana.put(url, json={"mark": 10, "comment": "x"}).status_code == 403

    comment = "The conclusion explains the error in Ks well."
    made = tina.put(url, json={"mark": 8.5, "comment": comment})
    assert made.status_code == 200, made.text
    assert (made.json()["mark"], made.json()["automaticMark"]) == (8.5, automatic)
    # The student sees the final mark and the comment; the automatic one stays on the hand-in.
    mine = ana.get(f"/api/assignments/{aid}").json()
    assert (mine["override"]["mark"], mine["override"]["comment"]) == (8.5, comment)
    assert mine["mine"][0]["mark"] == automatic
    seen = _standings(tara, aid)["ana"]
    assert (seen["mark"], seen["automaticMark"], seen["comment"], seen["overridden"]) == (
        8.5,
        automatic,
        comment,
        True,
    )
    assert _standings(tina, aid)["bea"]["state"] == "missing"
    # The LMS is told the final mark.
    assert [(r.student, r.mark, r.automatic_mark) for r in heard][-1] == ("ana", 8.5, automatic)
    # Grades: final mark, automatic mark, comment; in the spreadsheet form too.
    rows = {
        r["student"]: r
        for r in csv.DictReader(io.StringIO(tina.get("/api/courses/ctrl1/grades.csv").text))
    }
    assert (float(rows["ana"]["mark"]), float(rows["ana"]["automatic_mark"])) == (8.5, automatic)
    assert rows["ana"]["comment"] == comment
    assert (rows["bea"]["mark"], rows["bea"]["automatic_mark"], rows["bea"]["comment"]) == (
        "",
        "",
        "",
    )
    sheet = tina.get("/api/courses/ctrl1/grades.csv", params={"dialect": "pt-BR"}).text
    assert "Nota automática" in sheet.splitlines()[0]
    assert "Comentário do professor" in sheet.splitlines()[0]
    assert "8,5" in sheet
    assert comment in sheet
    # The analytics count the final mark.
    now = bench["clock"].now()
    window = {
        "from": (now - timedelta(days=1)).isoformat(),
        "to": (now + timedelta(seconds=1)).isoformat(),
    }
    analytics = tina.get("/api/courses/ctrl1/analytics", params=window)
    assert analytics.status_code == 200, analytics.text
    figures = analytics.json()["students"]
    ana_figures = next(s for s in figures if s["username"] == "ana")["assignments"]
    assert (ana_figures["marked"], ana_figures["meanMark"]) == (1, pytest.approx(85.0))
    # A later hand-in keeps the override, its automatic mark shown beside it.
    _hand_in(ana, aid, _run(lab, bench["ana_p"], samples=300), K=0.1401)
    again = _standings(tina, aid)["ana"]
    assert again["mark"] == 8.5
    assert again["automaticMark"] != automatic
    # Logged; removed, the automatic mark is the final one again.
    logged = lab.audit.list(action="assignment.mark_overridden")
    assert [(r.actor, r.target, r.detail["student"], r.detail["mark"]) for r in logged] == [
        ("tina", f"ctrl1 #{aid}", "ana", 8.5)
    ]
    assert tina.delete(url).status_code == 204
    assert ana.get(f"/api/assignments/{aid}").json()["override"] is None
    assert _standings(tina, aid)["ana"]["mark"] == again["automaticMark"]
    assert len(lab.audit.list(action="assignment.mark_override_removed")) == 1


def test_an_extension_lets_one_student_hand_in_after_the_deadline_without_being_late(
    bench: Any,
) -> None:
    lab: Lab = bench["lab"]
    clock: ManualClock = bench["clock"]
    tina, ana, bea = bench["tina"], bench["ana"], bench["bea"]
    aid = bench["assignment"]["id"]
    later = bench["deadline"] + timedelta(days=2)
    url = f"/api/assignments/{aid}/extensions/ana"
    early = tina.put(url, json={"deadline": bench["deadline"].isoformat()})
    assert (early.status_code, early.json()["code"]) == (422, "invalid_parameter")
    assert tina.put(url, json={"deadline": "2030-01-01T12:00:00"}).status_code == 422  # no zone
    assert bench["tara"].put(url, json={"deadline": later.isoformat()}).status_code == 403
    made = tina.put(url, json={"deadline": later.isoformat()})
    assert made.status_code == 200, made.text
    assert ana.get(f"/api/assignments/{aid}").json()["extendedDeadline"] == made.json()["deadline"]
    assert bea.get(f"/api/assignments/{aid}").json()["extendedDeadline"] is None

    ana_run, bea_run = (
        _run(lab, bench["ana_p"], samples=300),
        _run(lab, bench["bea_p"], samples=300),
    )
    people = {"tina": tina, "ana": ana, "bea": bea}
    _after(clock, 2 * 3600, people)  # after the assignment's deadline, before ana's
    assert _hand_in(ana, aid, ana_run)["late"] is False
    assert _hand_in(bea, aid, bea_run)["late"] is True
    seen = _standings(tina, aid)
    assert (seen["ana"]["extended"], seen["ana"]["late"]) == (True, False)
    assert (seen["bea"]["extended"], seen["bea"]["late"]) == (False, True)
    # An extension given after the fact (bea was ill) clears the flag; taken back, it returns.
    assert (
        tina.put(
            f"/api/assignments/{aid}/extensions/bea", json={"deadline": later.isoformat()}
        ).status_code
        == 200
    )
    assert _standings(tina, aid)["bea"]["late"] is False
    assert tina.delete(f"/api/assignments/{aid}/extensions/bea").status_code == 204
    assert _standings(tina, aid)["bea"]["late"] is True
    _after(clock, 3 * 86400, people)  # after ana's own deadline: late, as anyone's
    assert _hand_in(ana, aid, ana_run)["late"] is True
    # The assignment's deadline moved past ana's extension: the later one holds.
    moved = later + timedelta(days=10)
    body = _assignment(methods=["lsm"], settings={}, deadline=moved.isoformat())
    assert tina.put(f"/api/assignments/{aid}", json=body).status_code == 200
    assert datetime.fromisoformat(_standings(tina, aid)["ana"]["deadline"]) == moved
    assert ana.get(f"/api/assignments/{aid}").json()["extendedDeadline"] is None
    assert [r.detail["student"] for r in lab.audit.list(action="assignment.deadline_extended")] == [
        "bea",
        "ana",
    ]


def test_a_lab_group_hands_in_once_and_every_member_is_marked(bench: Any) -> None:
    lab: Lab = bench["lab"]
    tina, ana, bea, cid = bench["tina"], bench["ana"], bench["bea"], bench["cid"]
    aid = bench["assignment"]["id"]
    groups = "/api/courses/ctrl1/groups"
    refused = {
        "alone": ({"name": "solo", "members": ["ana", "ana"]}, 422),
        "not in the course": ({"name": "x", "members": ["ana", "ben"]}, 404),
        "no name": ({"name": " ", "members": ["ana", "bea"]}, 422),
    }
    for what, (body, code) in refused.items():
        answer = tina.post(groups, json=body)
        assert answer.status_code == code, (what, answer.text)
    assert (
        bench["tara"].post(groups, json={"name": "b", "members": ["ana", "bea"]}).status_code == 403
    )
    made = tina.post(groups, json={"name": "Bench  1", "members": ["bea", "ANA"]})
    assert made.status_code == 201, made.text
    group = made.json()
    assert (group["name"], [m["username"] for m in group["members"]]) == ("Bench 1", ["ana", "bea"])
    busy = tina.post(groups, json={"name": "Bench 2", "members": ["cid", "ana"]})
    assert busy.status_code == 409
    assert "ana (Bench 1)" in busy.json()["detail"]
    assert [g["name"] for g in bench["tara"].get(groups).json()] == ["Bench 1"]
    assert ana.get(groups).status_code == 403
    assert ana.get(f"/api/assignments/{aid}").json()["group"] == {
        "name": "Bench 1",
        "members": ["ana", "bea"],
    }

    # bea hands in ana's run for both: one hand-in each, marked the same.
    ana_run = _run(lab, bench["ana_p"], samples=300)
    handed = _hand_in(bea, aid, ana_run)
    assert handed["student"] == "bea"
    assert handed["handedInBy"] is None
    theirs = ana.get(f"/api/assignments/{aid}").json()["mine"]
    assert [(s["runId"], s["mark"], s["handedInBy"]) for s in theirs] == [
        (ana_run, handed["mark"], "bea")
    ]
    seen = _standings(tina, aid)
    assert (seen["ana"]["group"], seen["bea"]["group"], seen["cid"]["group"]) == (
        "Bench 1",
        "Bench 1",
        None,
    )
    assert seen["ana"]["mark"] == seen["bea"]["mark"] == handed["mark"]
    # Not a member: not their run.
    outsider = cid.post(
        f"/api/assignments/{aid}/submissions", json={"runId": ana_run, "K": 0.14, "tau": 250.0}
    )
    assert outsider.status_code == 403
    # An override is per student.
    tina.put(
        f"/api/assignments/{aid}/overrides/ana", json={"mark": 3, "comment": "absent at the rig"}
    )
    seen = _standings(tina, aid)
    assert (seen["ana"]["mark"], seen["bea"]["mark"]) == (3, handed["mark"])
    # Removed, each hands in alone again; the hand-ins stay.
    assert tina.delete(f"{groups}/{group['id']}").status_code == 204
    assert tina.delete(f"{groups}/{group['id']}").status_code == 404
    alone = bea.post(
        f"/api/assignments/{aid}/submissions", json={"runId": ana_run, "K": 0.14, "tau": 250.0}
    )
    assert alone.status_code == 403
    assert len(ana.get(f"/api/assignments/{aid}").json()["mine"]) == 1
    # bea removed from the lab: her name goes from the hand-in she made for ana too.
    pseudonym = forget_person(lab.db, "bea", "keep", "$argon2id$unknown")
    assert ana.get(f"/api/assignments/{aid}").json()["mine"][0]["handedInBy"] == pseudonym
    logged = [r.action for r in lab.audit.list() if r.action.startswith("course.group")]
    assert logged == ["course.group_removed", "course.group_created"]


def test_a_group_mate_reads_the_groups_runs_and_nothing_more(bench: Any) -> None:
    lab: Lab = bench["lab"]
    tina, ana, bea, cid, ben = (bench[n] for n in ("tina", "ana", "bea", "cid", "ben"))
    aid = bench["assignment"]["id"]
    lab.courses.create("ctrl2", "Controle II", "tina")
    lab.courses.import_class_list("ctrl2", b"username,display_name\nben,Ben\n")
    before = _run(lab, bench["ana_p"], samples=300)  # ana's own, before the group
    _after(bench["clock"], 60, {n: bench[n] for n in ("tina", "ana", "bea", "cid", "ben")})
    made = tina.post(
        "/api/courses/ctrl1/groups", json={"name": "Bench 1", "members": ["ana", "bea"]}
    )
    assert made.status_code == 201, made.text
    shared = _run(lab, bench["ana_p"], samples=300)  # the group's work at the rig

    def reads(client: TestClient, run_id: int) -> list[int]:
        paths = (f"/api/runs/{run_id}", f"/api/runs/{run_id}/samples.csv")
        paths += (f"/api/runs/{run_id}/export.json",)
        return [client.get(path).status_code for path in paths]

    assert reads(bea, shared) == [200, 200, 200]
    assert bea.get(f"/api/runs/{shared}").json()["username"] == "ana"
    rows = list(csv.reader(io.StringIO(bea.get(f"/api/runs/{shared}/samples.csv").text)))
    assert len(rows) > 300  # a header, then every sample
    assert bea.get(f"/api/runs/{shared}/export.json").json()["run"]["id"] == shared
    # Refused as any other student's run is: the same course not in the group, another course.
    for outsider in (cid, ben):
        assert reads(outsider, shared) == [403, 403, 403]
    assert (
        cid.get(f"/api/runs/{shared}").json()["code"]
        == ben.get(f"/api/runs/{shared}").json()["code"]
    )
    # Only the group's runs: ana's earlier run stays hers ...
    assert reads(bea, before) == [403, 403, 403]
    # ... until a mate hands it in for the group: then it is bea's hand-in too.
    _hand_in(ana, aid, before)
    assert reads(bea, before) == [200, 200, 200]
    assert reads(cid, before) == [403, 403, 403]
    # Reading only: no list of ana's runs, nothing to delete or change.
    assert bea.get("/api/runs?user=ana").status_code == 403
    assert [r["id"] for r in bea.get("/api/runs").json()] == []
    for method in ("DELETE", "PATCH", "PUT", "POST"):
        assert bea.request(method, f"/api/runs/{shared}").status_code == 405, method
    stop = bea.post("/api/rigs/twin/runs/current/stop")
    assert stop.status_code == 409, stop.text  # no run of hers (nor any) is going
    assert ana.get(f"/api/runs/{shared}").json()["status"] == "finished"
    # The group removed: each reads only their own again.
    assert tina.delete(f"/api/courses/ctrl1/groups/{made.json()['id']}").status_code == 204
    assert reads(bea, shared) == [403, 403, 403]
    assert reads(bea, before) == [403, 403, 403]
