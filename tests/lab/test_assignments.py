"""Assignments through the API on SQLite: set, hand in a real twin run, mark, export.

The runs are real: the paper's twin on a virtual clock, sampled, stored and
identified again by the library when handed in.
"""

from __future__ import annotations

import csv
import io
import threading
from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from thermolab.errors import ConflictError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.assignments import Answers, GradeRow
from thermolab.lab.clock import ManualClock
from thermolab.lab.error_messages import error_message
from thermolab.lab.runs.request import RunRequest
from thermolab.lab.service import Lab

from .conftest import PASSWORD, LabFactory
from .test_runs import twin_lab

# On SQLite alone: hand-in and marking rules (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only

# The paper twin's true model (the reference the marks are checked against).
TRUE_K, TRUE_TAU = 0.14009, 250.126233


def _client(lab: Lab, clients: list[TestClient], name: str) -> TestClient:
    from thermolab.lab.http.app import create_app

    client = TestClient(create_app(lab.config, lab=lab, sweep_interval=None))
    clients.append(client)
    answer = client.post("/api/session", json={"username": name, "password": PASSWORD})
    assert answer.status_code == 200, answer.text
    return client


@pytest.fixture
def school(make_lab: LabFactory, clock: ManualClock) -> Any:
    """A twin lab, teacher tina with course ``ctrl1``, students ana (in it) and ben (not)."""
    lab = twin_lab(make_lab)
    tina = lab.users.add("tina", PASSWORD, "teacher")
    ana = lab.users.add("ana", PASSWORD, "student", "-Ana")
    ben = lab.users.add("ben", PASSWORD, "student")
    lab.courses.create("ctrl1", "Controle I", "tina")
    lab.courses.import_class_list("ctrl1", b"username,display_name\nana,-Ana\n")
    clients: list[TestClient] = []
    people = {
        "lab": lab,
        "clock": clock,
        "tina": _client(lab, clients, "tina"),
        "ana": _client(lab, clients, "ana"),
        "ben": _client(lab, clients, "ben"),
        "ana_p": Principal(ana.id, ana.username, ana.role),
        "ben_p": Principal(ben.id, ben.username, ben.role),
        "tina_p": Principal(tina.id, tina.username, tina.role),
    }
    yield people
    for client in clients:
        client.close()


def _run(lab: Lab, who: Principal, rig: str = "twin", samples: int = 1500) -> int:
    lab.access.request_control(rig, who)
    request = RunRequest(dt=1.0, samples=samples, signal="step:0:10@5", methods=("lsm",))
    run = lab.runs.start(rig, who, request)
    lab.runs.wait(rig, timeout=60)
    lab.access.release(rig, who)
    return run.id


def _assignment(**changes: Any) -> dict[str, Any]:
    body: dict[str, Any] = {
        "title": "Step response of the box",
        "instructions": "Make a step of 10 V and find Ks, Ts.",
        "rig": "twin",
        "methods": ["lsm", "oe"],
        "settings": {"lsm": {"max_delay": 5}},
        "deadline": "2030-01-01T12:00:00+00:00",
        "tolerance": {"K": 0.05, "tau": 0.05, "theta": 5.0},
    }
    body.update(changes)
    return body


def test_a_teacher_sets_an_assignment_checked_by_the_method_registry(school: Any) -> None:
    tina: TestClient = school["tina"]
    made = tina.post("/api/courses/ctrl1/assignments", json=_assignment())
    assert made.status_code == 201, made.text
    out = made.json()
    assert out["methods"] == ["lsm", "oe"]
    assert out["tolerance"] == {"K": 0.05, "tau": 0.05, "theta": 5.0}
    refused = {
        "unknown method": (_assignment(methods=["magic"]), 422, "allowed: srm, lsm"),
        "bad setting": (_assignment(settings={"lsm": {"window": 5}}), 422, "allowed: order"),
        "out of range": (_assignment(settings={"oe": {"max_delay": -1}}), 422, "max_delay"),
        "unused method": (_assignment(settings={"wlsm": {}}), 422, "does not use"),
        "unknown rig": (_assignment(rig="oven"), 404, "no rig called 'oven'"),
        "naive deadline": (_assignment(deadline="2030-01-01T12:00:00"), 422, "timezone"),
        "tolerance": (_assignment(tolerance={"K": 2}), 422, "less than or equal to 1"),
    }
    for what, (body, code, words) in refused.items():
        answer = tina.post("/api/courses/ctrl1/assignments", json=body)
        assert answer.status_code == code, (what, answer.text)
        assert words in answer.text, (what, answer.text)
        assert "code" in answer.json()
    student = school["ana"].post("/api/courses/ctrl1/assignments", json=_assignment())
    assert student.status_code == 403
    changed = tina.put(f"/api/assignments/{out['id']}", json=_assignment(title="Renamed"))
    assert changed.json()["title"] == "Renamed"
    listing = school["ana"].get("/api/assignments").json()
    assert [a["title"] for a in listing] == ["Renamed"]
    assert school["ben"].get("/api/assignments").json() == []  # not in the course
    assert school["ben"].get(f"/api/assignments/{out['id']}").status_code == 403


def test_a_student_hands_in_a_twin_run_is_marked_and_the_teacher_exports_grades(
    school: Any,
) -> None:
    lab: Lab = school["lab"]
    clock: ManualClock = school["clock"]
    tina, ana = school["tina"], school["ana"]
    deadline = clock.now() + timedelta(seconds=60)
    made = tina.post(
        "/api/courses/ctrl1/assignments",
        json=_assignment(
            title="=1+1 step", deadline=deadline.isoformat(), methods=["lsm"], settings={}
        ),
    ).json()
    heard: list[GradeRow] = []
    lab.assignments.on_marked(heard.append)
    run_id = _run(lab, school["ana_p"])
    url = f"/api/assignments/{made['id']}/submissions"

    good = ana.post(url, json={"runId": run_id, "K": 0.1401, "tau": 250.0, "theta": 0.0})
    assert good.status_code == 201, good.text
    first = good.json()
    assert (first["state"], first["mark"], first["max"], first["late"]) == (
        "marked",
        10.0,
        10.0,
        False,
    )
    checks = first["assessment"]["checks"]
    assert {(c["quantity"], c["basis"]) for c in checks} == {
        (q, b) for q in ("K", "tau", "theta") for b in ("reference", "run")
    }
    reference = next(c for c in checks if c["basis"] == "reference" and c["quantity"] == "K")
    assert reference["target"] == pytest.approx(TRUE_K)
    assert reference["tolerance"] == "±5 %"
    assert first["assessment"]["identified"][0]["fit"] > 99
    assert [(r.student, r.mark, r.late) for r in heard] == [("ana", 10.0, False)]

    # After the deadline: a worse answer is kept, marked late, and is the current one.
    clock.advance(120)
    body = {"runId": run_id, "K": 0.2, "tau": 250.0, "theta": 0.0, "conclusion": "-1 ok"}
    late = ana.post(url, json=body)
    assert late.status_code == 201, late.text
    assert late.json()["late"] is True
    assert late.json()["mark"] == pytest.approx(10 * 4 / 6, abs=0.05)
    kept = ana.get(f"/api/assignments/{made['id']}").json()["mine"]
    assert [(s["late"], s["current"]) for s in kept] == [(True, True), (False, False)]
    k_fail = next(c for c in late.json()["assessment"]["checks"] if c["quantity"] == "K")
    assert k_fail["verdict"] == "fail"
    assert "more than ±5 %" in k_fail["why"]

    every = tina.get(url).json()
    assert [s["current"] for s in every] == [True, False]
    assert school["ana"].get(url).status_code == 403

    exported = tina.get("/api/courses/ctrl1/grades.csv")
    assert exported.status_code == 200
    assert exported.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(exported.text)))
    assert len(rows) == 1  # one student × one assignment
    row = rows[0]
    assert (row["student"], row["state"], row["late"]) == ("ana", "marked", "yes")
    # Never a formula in a spreadsheet.
    assert (row["display_name"], row["assignment"]) == ("'-Ana", "'=1+1 step")
    assert float(row["mark"]) == pytest.approx(6.7)
    assert (row["answer_K"], row["answer_tau"], row["answer_theta"]) == ("0.2", "250.0", "0.0")
    assert row["conclusion"] == "'-1 ok"
    assert school["ana"].get("/api/courses/ctrl1/grades.csv").status_code == 403
    rows_for_lti = lab.assignments.grade_rows("ctrl1")
    assert [(r.course, r.assignment_id, r.student, r.max) for r in rows_for_lti] == [
        ("ctrl1", made["id"], "ana", 10.0)
    ]


def test_a_hand_in_is_refused_for_a_run_that_is_not_the_students_or_not_on_the_rig(
    school: Any,
) -> None:
    lab: Lab = school["lab"]
    tina, ana, ben = school["tina"], school["ana"], school["ben"]
    made = tina.post("/api/courses/ctrl1/assignments", json=_assignment()).json()
    url = f"/api/assignments/{made['id']}/submissions"
    theirs = _run(lab, school["ben_p"])
    elsewhere = _run(lab, school["ana_p"], rig="other")
    short = _run(lab, school["ana_p"], samples=5)
    cases: list[tuple[dict[str, Any], int, str]] = [
        ({"runId": theirs, "K": 0.14, "tau": 250.0}, 403, "is not yours"),
        ({"runId": elsewhere, "K": 0.14, "tau": 250.0}, 409, "made on rig 'other'"),
        ({"runId": short, "K": 0.14, "tau": 250.0}, 409, "at least 10 are needed"),
        ({"runId": 999_999, "K": 0.14, "tau": 250.0}, 404, "no run 999999"),
        ({"runId": theirs, "K": 0.14, "tau": -1.0}, 422, "greater than 0"),
        ({"runId": theirs, "K": "NaN", "tau": 1.0}, 422, "invalid_request"),
    ]
    for body, code, words in cases:
        answer = ana.post(url, json=body)
        assert answer.status_code == code, (body, answer.text)
        assert words in answer.text, (body, answer.text)
    # Each refusal of a run its own code and sentence, in the student's language (#24).
    pt = {"Accept-Language": "pt-BR"}
    for run_id, why in ((elsewhere, "handin_wrong_rig"), (short, "handin_too_short")):
        answer = ana.post(url, json={"runId": run_id, "K": 0.14, "tau": 250.0}, headers=pt)
        assert (answer.json()["code"], answer.json()["message"]) == (
            why,
            error_message(why, "pt-BR"),
        )
        assert answer.json()["message"].startswith("Este ensaio")
    assert ben.post(url, json={"runId": theirs, "K": 0.14, "tau": 250.0}).status_code == 403
    assert tina.get(url).json() == []


def _hand_in_an_srm_step(school: Any, samples: int) -> dict[str, Any]:
    """ana hands in a step run of ``samples`` for an SRM assignment, with the true answers."""
    made = (
        school["tina"]
        .post("/api/courses/ctrl1/assignments", json=_assignment(methods=["srm"], settings={}))
        .json()
    )
    run_id = _run(school["lab"], school["ana_p"], samples=samples)
    answer: dict[str, Any] = (
        school["ana"]
        .post(
            f"/api/assignments/{made['id']}/submissions",
            json={"runId": run_id, "K": TRUE_K, "tau": TRUE_TAU, "theta": 0.0},
        )
        .json()
    )
    return answer


def test_an_untrustworthy_identification_gives_no_mark(school: Any) -> None:
    # 145 s of a 250 s time constant: the output never covers 63.2 % of its change, so
    # SRM's tau is extrapolated, and the library's verdict does not trust it.
    answer = _hand_in_an_srm_step(school, samples=150)
    assert (answer["state"], answer["mark"]) == ("review", None)
    assert any("not trustworthy" in n for n in answer["assessment"]["notes"])
    grades = school["tina"].get("/api/courses/ctrl1/grades.csv").text
    assert ",review,," in grades


def test_a_record_shorter_than_the_papers_count_is_marked_when_its_model_is_right(
    school: Any,
) -> None:
    # 600 samples, not the paper's 2000: a note, not a reason (issue #21); the model
    # follows the record and agrees with the output-error fit, so the mark is given.
    answer = _hand_in_an_srm_step(school, samples=600)
    assert (answer["state"], answer["mark"]) == ("marked", 10.0)
    (srm,) = answer["assessment"]["identified"]
    assert srm["trusted"] is True
    assert any(w.startswith("short record") for w in srm["warnings"]), srm


def test_hand_ins_at_the_same_time_leave_one_current_and_lose_none_silently(
    school: Any,
) -> None:
    lab: Lab = school["lab"]
    made = school["tina"].post("/api/courses/ctrl1/assignments", json=_assignment()).json()
    run_id = _run(lab, school["ana_p"])
    ana: Principal = school["ana_p"]
    outcomes: list[str] = []
    start = threading.Barrier(4)

    def hand_in(k: float) -> None:
        start.wait()
        try:
            lab.assignments.hand_in(made["id"], ana, run_id, Answers(k, 250.0, 0.0))
            outcomes.append("stored")
        except ConflictError:
            outcomes.append("conflict")  # told to try again: nothing half-stored

    threads = [threading.Thread(target=hand_in, args=(0.14 + i / 1000,)) for i in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    kept = lab.assignments.get(made["id"], ana).mine
    assert len(outcomes) == 4
    assert outcomes.count("stored") == len(kept) >= 1
    assert [s.current for s in kept].count(True) == 1
    assert kept[0].current  # the newest is the current one
