"""The retention period: people of courses closed long ago are removed (SQLite, PostgreSQL).

The lab's clock starts on 2026-01-01 00:00 UTC (``ManualClock``); the courses
close then, and the clock moves on by whole months.
"""

from __future__ import annotations

import time
from datetime import UTC, datetime

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from thermolab.lab.accounts.users import Principal
from thermolab.lab.classes.retention import ACTOR, months_before
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import RetentionPolicy, RigConfig
from thermolab.lab.db.models import Run, User
from thermolab.lab.http.app import create_app
from thermolab.lab.runs.request import RunRequest
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory

DAY = 24 * 3600.0


def _term(lab: Lab) -> int:
    """tina's ``ctrl1`` (ana, beto, carla) and ``ctrl2`` (beto, carla), and dora in no course.

    ana made a run. ``ctrl1`` closes now; ``ctrl2`` stays open. Returns ana's run.
    """
    people = {
        name: lab.users.add(name, PASSWORD, role)
        for name, role in (
            ("tina", "teacher"),
            ("ana", "student"),
            ("beto", "student"),
            ("carla", "student"),
            ("dora", "student"),
        )
    }
    lab.courses.create("ctrl1", "Controle I", "tina")
    lab.courses.import_class_list("ctrl1", b"username,display_name\nana,A\nbeto,B\ncarla,C\n")
    lab.courses.create("ctrl2", "Controle II", "tina")
    lab.courses.import_class_list("ctrl2", b"username,display_name\nbeto,B\ncarla,C\n")
    ana = Principal(people["ana"].id, "ana", people["ana"].role)
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, RunRequest(dt=1.0, samples=10, signal="step:0:10@3"))
    lab.runs.wait("twin", timeout=60)
    lab.access.release("twin", ana)
    lab.term.close("ctrl1", "tina")
    return run.id


def _lab(make_lab: LabFactory, policy: RetentionPolicy) -> Lab:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper" if rig.id == "twin" else "tclab", clock=VirtualClock())

    return make_lab(opener=opener, retention=policy)


def _names(lab: Lab) -> set[str]:
    with lab.db.read() as session:
        return set(session.scalars(select(User.username)))


def _runs(lab: Lab, run_id: int) -> int:
    with lab.db.read() as session:
        return session.scalar(select(func.count()).select_from(Run).where(Run.id == run_id)) or 0


def test_students_of_courses_closed_longer_than_the_period_are_pseudonymised(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = _lab(make_lab, RetentionPolicy(6))
    run = _term(lab)
    # Within the period: nobody is due.
    clock.advance(150 * DAY)
    assert lab.retention.due().due == []
    assert lab.retention.apply().removed == []
    # Past it, ana (in ctrl1 only) is; beto and carla are in the open ctrl2; dora in no course.
    clock.advance(40 * DAY)
    due = lab.retention.due()
    assert due.cutoff == months_before(clock.now(), 6)
    assert [(p.username, p.last_closed.date().isoformat()) for p in due.due] == [
        ("ana", "2026-01-01")
    ]
    assert "ana" in _names(lab)  # the dry run changed nothing
    report = lab.retention.apply()
    [pseudonym] = report.removed
    assert pseudonym.startswith("removed-")
    names = _names(lab)
    assert "ana" not in names
    assert {"tina", "beto", "carla", "dora", pseudonym} <= names
    assert _runs(lab, run) == 1  # kept under the pseudonym, for the class's statistics
    [entry] = [e for e in lab.audit.list() if e.actor == ACTOR]
    assert (entry.action, entry.target) == ("account.forgotten", pseudonym)
    assert entry.detail == {
        "runs": "keep",
        "retention_months": 6,
        "last_course_closed": "2026-01-01",
    }
    # A second pass finds nobody: the pseudonymised row is no one's any more.
    assert lab.retention.apply().due == []
    # ctrl2 closes: its students go once the period has passed since *that* close.
    lab.term.close("ctrl2", "tina")
    clock.advance(170 * DAY)
    assert lab.retention.due().due == []
    clock.advance(20 * DAY)
    assert [p.username for p in lab.retention.due().due] == ["beto", "carla"]
    assert len(lab.retention.apply().removed) == 2
    assert {"tina", "dora"} <= _names(lab)  # teachers and people in no course stay


def test_delete_takes_their_runs_and_unset_removes_nobody(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = _lab(make_lab, RetentionPolicy(1, "delete"))
    run = _term(lab)
    clock.advance(40 * DAY)
    assert len(lab.retention.apply().removed) == 1
    assert _runs(lab, run) == 0
    assert "ana" not in _names(lab)
    [entry] = [e for e in lab.audit.list() if e.actor == ACTOR]
    assert entry.detail["runs"] == "delete"
    # Unset: however long ago a course closed, nobody is ever removed.
    unset = lab.retention
    unset.policy = RetentionPolicy()
    lab.term.close("ctrl2", "tina")
    clock.advance(3650 * DAY)
    report = unset.apply()
    assert (report.cutoff, report.due, report.removed) == (None, [], [])
    assert {"beto", "carla"} <= _names(lab)


def test_the_server_applies_the_period_at_its_start_and_then_on_its_own(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = _lab(make_lab, RetentionPolicy(6))
    _term(lab)
    app = create_app(lab.config, lab=lab, sweep_interval=None, retention_interval=0.05)
    with TestClient(app):
        time.sleep(0.3)  # a few passes, none due yet
        assert "ana" in _names(lab)
        clock.advance(200 * DAY)

        def audited() -> list[str]:
            return [e.action for e in lab.audit.list() if e.actor == ACTOR]

        # The removal and its audit entry (one transaction): wait for the server's pass.
        deadline = time.monotonic() + 30
        while not audited() and time.monotonic() < deadline:
            time.sleep(0.05)  # real time: the server's own pass, on its own thread
        assert "ana" not in _names(lab)
        assert audited() == ["account.forgotten"]
    assert audited() == ["account.forgotten"]


@pytest.mark.parametrize(
    ("t", "months", "expected"),
    [
        (datetime(2027, 3, 31, 9, tzinfo=UTC), 1, datetime(2027, 2, 28, 9, tzinfo=UTC)),
        (datetime(2028, 3, 31, tzinfo=UTC), 1, datetime(2028, 2, 29, tzinfo=UTC)),
        (datetime(2027, 1, 15, tzinfo=UTC), 12, datetime(2026, 1, 15, tzinfo=UTC)),
        (datetime(2027, 1, 15, tzinfo=UTC), 25, datetime(2024, 12, 15, tzinfo=UTC)),
    ],
)
def test_months_are_calendar_months(t: datetime, months: int, expected: datetime) -> None:
    assert months_before(t, months) == expected


def test_the_privacy_page_is_told_the_period_without_a_login(make_lab: LabFactory) -> None:
    lab = make_lab(retention=RetentionPolicy(18, "delete"))
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as anonymous:
        answer = anonymous.get("/api/privacy")
        assert answer.status_code == 200, answer.text
        assert answer.json() == {"retentionMonths": 18, "retentionAction": "delete"}
        lab.retention.policy = RetentionPolicy()
        unset = anonymous.get("/api/privacy").json()
        assert unset == {"retentionMonths": None, "retentionAction": "pseudonymise"}
