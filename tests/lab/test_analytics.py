"""Class analytics on hand-built records whose answers are known (SQLite and PostgreSQL)."""

from __future__ import annotations

import csv
import io
import uuid
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from sqlalchemy import Column, Float, MetaData, String, Table, create_engine, select

from thermolab.errors import InvalidParameterError, NotFoundError
from thermolab.lab.analytics.export import safe_cell
from thermolab.lab.analytics.sql import percentile
from thermolab.lab.clock import ManualClock
from thermolab.lab.db.assignment_models import Assignment, Submission
from thermolab.lab.db.models import (
    ControlSession,
    CourseMember,
    MethodResultRow,
    QueueEntry,
    Run,
    User,
)
from thermolab.lab.db.power_models import PowerChange
from thermolab.lab.service import Lab

from .conftest import PASSWORD

Clients = Callable[..., TestClient]
H = 3600.0
START = datetime(2026, 1, 1, tzinfo=UTC)  # the manual clock's start: the lab's power history begins
B = START + timedelta(hours=1)  # the window's start
END = B + timedelta(hours=10)  # the window's end
NOW = B + timedelta(hours=11)
CALC = "-Caio"  # a display name a spreadsheet would read as a formula


def _at(seconds: float) -> datetime:
    return B + timedelta(seconds=seconds)


def _result(
    K: float, tau: float, *, valid: bool = True, flag: bool | None = None, warnings: int = 0
) -> dict[str, Any]:
    extras: dict[str, Any] = {"theta": 1.5, "warnings": ["w"] * warnings}
    if flag is not None:
        extras["trusted"] = flag
    return {
        "name": "m",
        "estimates": 3,
        "latest": {"K": K, "tau": tau, "valid": valid, "W": [0.9, 0.01], "extras": extras},
        "final": True,
        "error": None,
        "trajectory": {"k": [0, 1, 2], "K": [K] * 3, "tau": [tau] * 3, "valid": [True] * 3},
        "stats": {"converged": True},
    }


@pytest.fixture
def course(lab: Lab, clock: ManualClock) -> dict[str, int]:
    """Course ``ctrl1`` (tina teaching ana, bia, caio; zed outside) and its records."""
    assert clock.now() == START
    lab.users.add("tina", PASSWORD, "teacher")
    for name in ("ana", "bia", "caio", "zed"):
        lab.users.add(name, PASSWORD, "student", display_name=CALC if name == "caio" else None)
    lab.courses.create("ctrl1", "Controle I", "tina")
    clock.advance((NOW - START).total_seconds())
    with lab.db.write() as s:
        ids = {u.username: u.id for u in s.scalars(select(User))}
        course_id = lab_course_id(s)
        for name in ("ana", "bia", "caio"):
            s.add(CourseMember(course_id=course_id, user_id=ids[name], role="student", joined_at=B))

        def turn(
            rig: str, who: str, start: float, end: float | None, why: str = "released"
        ) -> None:
            s.add(
                ControlSession(
                    rig_id=rig,
                    user_id=ids[who],
                    username=who,
                    started_at=_at(start),
                    deadline=_at(start + 300),
                    last_heartbeat_at=_at(start),
                    last_activity_at=_at(start),
                    ended_at=None if end is None else _at(end),
                    end_reason=None if end is None else why,
                )
            )

        turn("twin", "ana", -100, 200)  # straddles the window's start: 200 s inside
        turn("twin", "ana", H, H + 600)
        turn("twin", "bia", 2 * H, 2 * H + 300)
        turn("twin", "zed", 3 * H, 3 * H + 1000, "rig_fault")  # not the course's; the rig's fault
        turn("twin", "ana", 10 * H + 5, 10 * H + 50)  # after the window
        turn("other", "caio", 4 * H, None)  # still at the controls: to the window's end

        def run(who: str, start: float, status: str, reason: str, results: dict[str, Any]) -> None:
            row = Run(
                rig_id="twin",
                user_id=ids[who],
                status=status,
                dt=1.0,
                n_samples=10,
                signal="step:0:5@1",
                methods=list(results),
                meta={},
                started_at=_at(start),
                ended_at=_at(start + 10),
                end_reason=reason,
                samples_stored=10,
            )
            s.add(row)
            s.flush()
            for method, result in results.items():
                s.add(
                    MethodResultRow(
                        run_id=row.id,
                        label=method,
                        method=method,
                        params={},
                        result=result,
                        created_at=_at(start + 10),
                    )
                )

        run("ana", -50, "finished", "completed", {"wlsm": _result(9.0, 9.0)})  # before the window
        run(
            "ana",
            H + 10,
            "finished",
            "completed",
            {"lsm": _result(0.14, 250.0, flag=True), "srm": _result(0.13, 240.0)},
        )
        run("ana", H + 300, "stopped", "ended by ana", {"lsm": _result(0.15, 260.0, flag=False)})
        run("bia", 2 * H + 10, "failed", "interlock: output 95 over its limit 90", {})
        run("bia", 2 * H + 100, "interrupted", "the server stopped during the run", {})
        run("bia", 2 * H + 200, "finished", "completed", {"wlsm": _result(0.2, 100.0, warnings=2)})
        run("zed", 3 * H + 10, "finished", "completed", {"lsm": _result(1.0, 1.0)})

        ticket = iter(range(1, 100))

        def wait(rig: str, who: str, joined: float, seconds: float, why: str = "promoted") -> None:
            s.add(
                QueueEntry(
                    rig_id=rig,
                    user_id=ids[who],
                    ticket=next(ticket),
                    joined_at=_at(joined),
                    last_heartbeat_at=_at(joined),
                    left_at=_at(joined + seconds),
                    leave_reason=why,
                )
            )

        for i, seconds in enumerate((40.0, 10.0, 100.0, 30.0, 20.0)):
            wait("twin", ("ana", "bia")[i % 2], H * (i + 1) - seconds, seconds)
        wait("twin", "ana", 5 * H, 5000.0, "left")  # gave up: not a wait for control
        wait("twin", "zed", 6 * H, 999.0)  # not the course's
        wait("twin", "bia", -500, 450.0)  # got control before the window
        wait("other", "caio", 4 * H - 7, 7.0)

        def power(rig: str, seconds: float, state: str) -> None:
            s.add(PowerChange(rig_id=rig, at=_at(seconds), state=state))

        power("twin", H, "on")
        power("twin", H + 900, "off")
        power("twin", 2 * H, "cooling")
        power("twin", 2 * H + 600, "off")
        power("twin", 9 * H + 50 * 60, "on")  # still on now: 600 s inside the window
        power("other", -H, "on")
        power("other", 100, "off")  # 100 s inside
    return ids


def lab_course_id(session: Any) -> int:
    from thermolab.lab.db.models import Course

    return session.scalars(select(Course.id).where(Course.name == "ctrl1")).one()


def test_the_figures_of_each_student_are_the_hand_counted_ones(
    lab: Lab, course: dict[str, int]
) -> None:
    data = lab.analytics.course("ctrl1", B, END)
    assert (data.window.start, data.window.end, data.computed_at) == (B, END, NOW)
    by = {s.username: s for s in data.students}
    assert list(by) == ["ana", "bia", "caio"]  # zed and the teacher are not the course's students
    ana, bia, caio = by["ana"], by["bia"], by["caio"]
    assert_allclose([ana.control_seconds, bia.control_seconds], [800.0, 300.0], atol=1e-3)
    assert_allclose(
        caio.control_seconds, 6 * H, atol=1e-3
    )  # open turn, clipped at the window's end
    assert (ana.turns, bia.turns, caio.turns) == (2, 1, 1)
    assert (ana.runs["finished"], ana.runs["stopped"], ana.run_count) == (1, 1, 2)
    assert (bia.runs["failed"], bia.runs["interrupted"], bia.runs["finished"]) == (1, 1, 1)
    assert caio.run_count == 0
    assert caio.results == ()
    results = {r.method: r for r in ana.results}
    assert sorted(results) == ["lsm", "srm"]  # wlsm was before the window
    lsm, srm = results["lsm"], results["srm"]
    assert (lsm.runs, lsm.K, lsm.tau, lsm.theta, lsm.trusted) == (2, 0.15, 260.0, 1.5, False)
    assert lsm.at == _at(H + 300)  # the newest run's, flagged untrusted by the library
    assert (srm.runs, srm.K, srm.tau, srm.trusted) == (1, 0.13, 240.0, True)
    (wlsm,) = bia.results
    assert (wlsm.method, wlsm.K, wlsm.trusted) == ("wlsm", 0.2, False)  # warnings, no flag
    assert all(s.assignments is None for s in data.students)


def test_the_figures_of_each_rig_are_the_hand_counted_ones(
    lab: Lab, course: dict[str, int]
) -> None:
    data = lab.analytics.course("ctrl1", B, END)
    twin, other = data.rigs
    assert (twin.rig, other.rig) == ("twin", "other")
    assert_allclose([twin.control_seconds, other.control_seconds], [1100.0, 6 * H], atol=1e-3)
    assert (twin.turns, twin.students, other.students) == (3, 2, 1)
    assert (twin.runs, twin.failed_runs, twin.interlock_runs, twin.rig_faults) == (5, 1, 1, 1)
    assert (other.runs, other.rig_faults) == (0, 0)
    waits = [40.0, 10.0, 100.0, 30.0, 20.0]
    assert twin.waits.count == 5
    assert_allclose([twin.waits.median, twin.waits.p90], np.percentile(waits, [50, 90]), atol=1e-3)
    assert_allclose([twin.waits.p90], [76.0], atol=1e-3)
    assert other.waits.count == 1
    assert_allclose([other.waits.median, other.waits.p90], [7.0, 7.0], atol=1e-3)
    assert_allclose([twin.powered_seconds, other.powered_seconds], [2100.0, 100.0], atol=1e-3)
    assert twin.power_recorded_since == START  # the lab's start wrote the first change


def test_a_narrow_window_clips_and_the_default_runs_from_the_course_to_now(
    lab: Lab, course: dict[str, int]
) -> None:
    data = lab.analytics.course("ctrl1", _at(H + 300), _at(2 * H + 150))
    by = {s.username: s for s in data.students}
    assert_allclose(
        [by["ana"].control_seconds, by["bia"].control_seconds], [300.0, 150.0], atol=1e-3
    )
    assert by["ana"].run_count == 1
    assert by["bia"].run_count == 2
    twin = data.rigs[0]
    assert_allclose(twin.powered_seconds, 600.0 + 150.0, atol=1e-3)
    assert twin.waits.count == 1  # only the wait that ended at 2 h
    whole = lab.analytics.course("ctrl1")
    assert (whole.window.start, whole.window.end) == (START, NOW)
    by = {s.username: s for s in whole.students}
    assert_allclose(by["ana"].control_seconds, 300.0 + 600.0 + 45.0, atol=1e-3)
    assert by["ana"].run_count == 3


def test_the_power_history_is_written_by_the_access_model(lab: Lab, clock: ManualClock) -> None:
    lab.users.add("ana", PASSWORD, "student")
    ana = lab.users.verify("ana", PASSWORD)
    with lab.db.read() as s:
        before = s.scalars(select(PowerChange.state).where(PowerChange.rig_id == "twin")).all()
    assert list(before) == ["off"]
    lab.access.request_control("twin", principal_of(lab, ana.username))
    clock.advance(30)
    lab.access.release("twin", principal_of(lab, ana.username))
    clock.advance(lab.config.rig("twin").power_off_grace + 1)
    lab.sweep()
    with lab.db.read() as s:
        rows = s.execute(
            select(PowerChange.state, PowerChange.at)
            .where(PowerChange.rig_id == "twin")
            .order_by(PowerChange.id)
        ).all()
    assert [state for state, _ in rows] == ["off", "on", "off"]
    assert rows[2][1] - rows[1][1] >= timedelta(seconds=30 + lab.config.rig("twin").power_off_grace)


def principal_of(lab: Lab, username: str) -> Any:
    from thermolab.lab.accounts.users import Principal

    info = lab.users.get(username)
    return Principal(info.id, info.username, info.role)


def test_bad_windows_and_unknown_courses_are_refused(lab: Lab, course: dict[str, int]) -> None:
    with pytest.raises(InvalidParameterError, match="empty"):
        lab.analytics.course("ctrl1", END, B)
    with pytest.raises(InvalidParameterError, match="longer"):
        lab.analytics.course("ctrl1", B - timedelta(days=4000), END)
    with pytest.raises(NotFoundError):
        lab.analytics.course("nope", B, END)


def test_the_api_is_for_teachers_and_matches_the_figures(
    lab: Lab, course: dict[str, int], app_client: Clients
) -> None:
    teacher, student = app_client("tina"), app_client("ana")
    window = {"from": B.isoformat(), "to": "2026-01-01T11:00:00Z"}
    got = teacher.get("/api/courses/ctrl1/analytics", params=window)
    assert got.status_code == 200, got.text
    body = got.json()
    assert body["windowFrom"] == "2026-01-01T01:00:00Z"
    assert body["windowTo"] == "2026-01-01T11:00:00Z"
    ana = body["students"][0]
    assert ana["username"] == "ana"
    assert ana["runsByStatus"]["stopped"] == 1
    assert ana["assignments"] is None
    assert {r["method"]: r["trusted"] for r in ana["results"]} == {"lsm": False, "srm": True}
    twin = body["rigs"][0]
    assert twin["waits"]["count"] == 5
    assert twin["waits"]["p90"] == pytest.approx(76.0, abs=1e-3)
    for path in ("", "/students.csv", "/rigs.csv"):
        refused = student.get(f"/api/courses/ctrl1/analytics{path}")
        assert refused.status_code == 403
        assert refused.json()["code"] == "access_denied"
    assert teacher.get("/api/courses/nope/analytics").json()["code"] == "not_found"


@pytest.mark.parametrize(
    ("query", "code"),
    [
        ("from=2026-01-02&to=2026-01-01", "invalid_parameter"),
        ("from=2026-02-30", "invalid_parameter"),
        ("to=yesterday", "invalid_request"),
        ("from=2026-01-01T00:00:00%2B99:99", "invalid_parameter"),
    ],
)
def test_a_bad_window_is_a_422_with_a_stable_code(
    lab: Lab, course: dict[str, int], app_client: Clients, query: str, code: str
) -> None:
    response = app_client("tina").get(f"/api/courses/ctrl1/analytics?{query}")
    assert response.status_code == 422, response.text
    assert response.json()["code"] == code


def test_both_tables_download_as_formula_safe_csv(
    lab: Lab, course: dict[str, int], app_client: Clients
) -> None:
    teacher = app_client("tina")
    window = {"from": "2026-01-01T01:00:00Z", "to": "2026-01-01T11:00:00Z"}
    students = teacher.get("/api/courses/ctrl1/analytics/students.csv", params=window)
    assert students.status_code == 200
    assert students.headers["content-type"].startswith("text/csv")
    assert 'filename="ctrl1-students.csv"' in students.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(students.text)))
    assert [r["username"] for r in rows] == ["ana", "bia", "caio"]
    ana, caio = rows[0], rows[2]
    assert float(ana["control_seconds"]) == pytest.approx(800.0, abs=1e-3)
    assert (ana["runs"], ana["runs_stopped"], ana["lsm_runs"], ana["lsm_K"]) == (
        "2",
        "1",
        "2",
        "0.15",
    )
    assert (ana["srm_trusted"], ana["lsm_trusted"], ana["wlsm_K"]) == ("true", "false", "")
    assert caio["display_name"] == "'" + CALC  # a spreadsheet shows it as text, never runs it
    assert caio["assignments_assigned"] == ""
    rigs = list(
        csv.DictReader(
            io.StringIO(teacher.get("/api/courses/ctrl1/analytics/rigs.csv", params=window).text)
        )
    )
    assert [r["rig"] for r in rigs] == ["twin", "other"]
    assert float(rigs[0]["wait_median_seconds"]) == pytest.approx(30.0, abs=1e-3)
    assert float(rigs[0]["powered_seconds"]) == pytest.approx(2100.0, abs=1e-3)
    assert rigs[1]["wait_p90_seconds"] == "7.0"
    # The spreadsheet form of both: headings in Portuguese, decimal commas, yes/no in words.
    sheet = {**window, "dialect": "pt-BR", "tz": "America/Sao_Paulo"}
    people = teacher.get("/api/courses/ctrl1/analytics/students.csv", params=sheet)
    text = people.content.decode("utf-8-sig")
    ana = next(csv.DictReader(io.StringIO(text), delimiter=";"))
    assert (ana["Nome de login"], ana["Tempo no controle (s)"], ana["Ensaios parados"]) == (
        "ana",
        "800",
        "1",
    )
    assert (ana["LSM: Ks"], ana["LSM: confiável"], ana["SRM: confiável"]) == ("0,15", "não", "sim")
    machines = teacher.get("/api/courses/ctrl1/analytics/rigs.csv", params=sheet)
    text = machines.content.decode("utf-8-sig")
    twin = next(csv.DictReader(io.StringIO(text), delimiter=";"))
    assert (twin["Bancada"], twin["Espera mediana (s)"], twin["Tempo ligada (s)"]) == (
        "twin",
        "30",
        "2100",
    )
    assert "Energia registrada desde (America/Sao_Paulo)" in twin


@pytest.fixture
def assignments(lab: Lab, course: dict[str, int]) -> None:
    """Assignments of ``ctrl1`` (and one of ``ctrl2``) and hand-ins with known answers.

    Open during [B, END): a1 (set before B, due at B + 2 h) and a2 (set at
    B + 3 h, due after END). Not counted: a3 (set after END), a4 (due before
    B), a5 (another course's).
    """
    lab.courses.create("ctrl2", "Controle II", "tina")
    ids = course
    with lab.db.write() as s:
        from thermolab.lab.db.models import Course

        ctrl1 = lab_course_id(s)
        ctrl2 = s.scalars(select(Course.id).where(Course.name == "ctrl2")).one()

        def assignment(course_id: int, created: float, due: float) -> int:
            row = Assignment(
                course_id=course_id,
                title="Step test",
                instructions="",
                rig_id="twin",
                methods=["lsm"],
                settings={},
                tol_k=0.1,
                tol_tau=0.1,
                tol_theta=None,
                deadline=_at(due),
                created_by="tina",
                created_at=_at(created),
                updated_at=_at(created),
            )
            s.add(row)
            s.flush()
            return row.id

        a1 = assignment(ctrl1, -H, 2 * H)
        a2 = assignment(ctrl1, 3 * H, 20 * H)
        a3 = assignment(ctrl1, 10 * H + 1, 30 * H)
        a4 = assignment(ctrl1, -2 * H, -600)
        a5 = assignment(ctrl2, 0, 2 * H)

        def hand_in(
            a: int,
            who: str,
            mark: float | None,
            max_mark: float,
            *,
            late: bool = False,
            current: bool = True,
        ) -> None:
            s.add(
                Submission(
                    assignment_id=a,
                    user_id=ids[who],
                    username=who,
                    run_id=None,
                    answers={},
                    submitted_at=_at(H),
                    late=late,
                    current=current,
                    state="review" if mark is None else "marked",
                    mark=mark,
                    max_mark=max_mark,
                    assessment={},
                    marked_at=_at(H),
                )
            )

        hand_in(a1, "ana", 0.0, 4.0, current=False)  # superseded: not counted
        hand_in(a1, "ana", 3.0, 4.0)  # 75 %
        hand_in(a2, "ana", 1.0, 2.0, late=True)  # 50 %
        hand_in(a1, "bia", None, 4.0, late=True)  # handed in, late, not marked (review)
        hand_in(a3, "bia", 4.0, 4.0)  # a3 is not counted
        hand_in(a4, "caio", 4.0, 4.0)  # a4 is not counted
        hand_in(a5, "caio", 4.0, 4.0)  # another course's
        hand_in(a1, "zed", 4.0, 4.0)  # not the course's student


def test_each_students_assignment_state_is_the_hand_counted_one(
    lab: Lab, assignments: None
) -> None:
    data = lab.analytics.course("ctrl1", B, END)
    by = {s.username: s.assignments for s in data.students}
    assert list(by) == ["ana", "bia", "caio"]
    ana, bia, caio = by["ana"], by["bia"], by["caio"]
    assert ana is not None
    assert bia is not None
    assert caio is not None
    assert (ana.assigned, ana.submitted, ana.late, ana.marked) == (2, 2, 1, 2)
    assert ana.mean_mark == pytest.approx(62.5)
    assert (bia.assigned, bia.submitted, bia.late, bia.marked, bia.mean_mark) == (
        2,
        1,
        1,
        0,
        None,
    )
    assert (caio.assigned, caio.submitted, caio.late, caio.marked, caio.mean_mark) == (
        2,
        0,
        0,
        0,
        None,
    )
    # The window's edges: a1 alone (a2 is set at 3 h); a4 alone (a1 is set at its end); none.
    early = {
        s.username: s.assignments for s in lab.analytics.course("ctrl1", B, _at(3 * H)).students
    }
    assert early["ana"] is not None
    assert (early["ana"].assigned, early["ana"].submitted, early["ana"].mean_mark) == (1, 1, 75.0)
    before = {
        s.username: s.assignments
        for s in lab.analytics.course("ctrl1", _at(-2 * H + 60), _at(-H)).students
    }
    assert before["caio"] is not None
    assert (before["caio"].assigned, before["caio"].marked, before["caio"].mean_mark) == (
        1,
        1,
        100.0,
    )
    assert before["ana"] is not None
    assert before["ana"].submitted == 0
    quiet = lab.analytics.course("ctrl1", _at(-3 * H), _at(-2 * H))
    assert all(s.assignments is None for s in quiet.students)


def test_the_assignment_state_reaches_the_api_and_the_csv(
    lab: Lab, assignments: None, app_client: Clients
) -> None:
    teacher = app_client("tina")
    window = {"from": B.isoformat(), "to": END.isoformat()}
    body = teacher.get("/api/courses/ctrl1/analytics", params=window).json()
    by = {s["username"]: s["assignments"] for s in body["students"]}
    assert by["ana"] == {"assigned": 2, "submitted": 2, "late": 1, "marked": 2, "meanMark": 62.5}
    assert by["caio"]["meanMark"] is None
    text = teacher.get("/api/courses/ctrl1/analytics/students.csv", params=window).text
    rows = {r["username"]: r for r in csv.DictReader(io.StringIO(text))}
    got = [rows["bia"][f"assignments_{k}"] for k in ("assigned", "submitted", "late", "marked")]
    assert got == ["2", "1", "1", "0"]
    assert rows["bia"]["assignments_mean_mark"] == ""
    assert float(rows["ana"]["assignments_mean_mark"]) == pytest.approx(62.5)
    # The spreadsheet form: the mean mark says it is a percentage, to one decimal as shown.
    sheet = teacher.get(
        "/api/courses/ctrl1/analytics/students.csv", params={**window, "dialect": "pt-BR"}
    )
    text = sheet.content.decode("utf-8-sig")
    people = {r["Nome de login"]: r for r in csv.DictReader(io.StringIO(text), delimiter=";")}
    assert people["ana"]["Nota média (% da máxima)"] == "62,5"
    assert (people["bia"]["Atividades propostas"], people["bia"]["Nota média (% da máxima)"]) == (
        "2",
        "",
    )


@pytest.mark.parametrize("text", ["=1+1", "+1", "-1", "@SUM(A1)", "\tx", "\rx"])
def test_text_that_looks_like_a_formula_is_defused(text: str) -> None:
    assert safe_cell(text) == "'" + text
    assert safe_cell("Ana -1") == "Ana -1"
    assert safe_cell(-1.0) == "-1.0"  # a number: not defused
    assert safe_cell(250.12623300000004) == "250.126233"  # and without float noise


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    groups=st.lists(
        # Waits are differences of stored times (microseconds): never subnormal, whose
        # interpolation weight's product PostgreSQL refuses as an underflow.
        st.lists(
            st.floats(0.0, 1e5, allow_nan=False, allow_subnormal=False), min_size=1, max_size=25
        ),
        min_size=1,
        max_size=3,
    )
)
def test_the_sql_percentiles_are_numpys_on_any_data(
    database_url: str, groups: list[list[float]]
) -> None:
    engine = create_engine(database_url)
    table = Table(
        f"waits_{uuid.uuid4().hex[:8]}",
        MetaData(),
        Column("key", String(8)),
        Column("value", Float),
    )
    try:
        table.create(engine)
        with engine.begin() as connection:
            connection.execute(
                table.insert(),
                [{"key": f"g{i}", "value": v} for i, values in enumerate(groups) for v in values],
            )
            query = percentile(
                select(table.c.key, table.c.value),
                "key",
                "value",
                {"median": (1, 2), "p90": (9, 10)},
            )
            got = {key: (n, median, p90) for key, n, median, p90 in connection.execute(query)}
        for i, values in enumerate(groups):
            n, median, p90 = got[f"g{i}"]
            assert n == len(values)
            assert_allclose(
                [float(median), float(p90)], np.percentile(values, [50, 90]), rtol=1e-9, atol=1e-6
            )
    finally:
        table.drop(engine, checkfirst=True)
        engine.dispose()
