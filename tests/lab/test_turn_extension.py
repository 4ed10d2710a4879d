"""A controller extends their own turn: only while nobody waits, in its last minute, bounded."""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta

import pytest
from fastapi.testclient import TestClient

from thermolab.errors import AccessDeniedError, ConflictError, TurnExtensionRefusedError
from thermolab.lab.access.extension import EXTEND_WINDOW, MAX_TURN_EXTENSIONS, TURN_EXTENSION
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.http.app import create_app
from thermolab.lab.service import Lab

from .conftest import PASSWORD, LabFactory

# On SQLite alone: turn rules on a manual clock (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only

Client = Callable[..., TestClient]


def _person(lab: Lab, name: str) -> Principal:
    info = lab.users.add(name, PASSWORD, "student")
    return Principal(info.id, info.username, info.role)


def _wait(lab: Lab, clock: ManualClock, who: Principal, seconds: float, *more: Principal) -> None:
    """Let time pass with these users' pages alive (heartbeats every 10 s)."""
    while seconds > 0:
        step = min(10.0, seconds)
        clock.advance(step)
        seconds -= step
        for person in (who, *more):
            lab.access.heartbeat("twin", person)


def test_the_controller_extends_in_the_last_minute_at_most_twice(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = make_lab(control_time_limit=300, idle_limit=None)
    ana = _person(lab, "ana")
    view = lab.access.request_control("twin", ana)
    assert view.access.can_extend is False  # five minutes left: too early
    with pytest.raises(TurnExtensionRefusedError, match="last 60 s only"):
        lab.access.extend_own("twin", ana)
    _wait(lab, clock, ana, 300 - EXTEND_WINDOW + 10)
    assert lab.access.view("twin", ana).access.can_extend is True
    for _ in range(MAX_TURN_EXTENSIONS):
        left = lab.access.view("twin", ana).access.time_left
        assert left is not None
        after = lab.access.extend_own("twin", ana).access.time_left
        assert after == pytest.approx(left + TURN_EXTENSION)
        _wait(lab, clock, ana, TURN_EXTENSION)
    assert lab.access.view("twin", ana).access.can_extend is False
    with pytest.raises(TurnExtensionRefusedError, match="already extended as far as allowed"):
        lab.access.extend_own("twin", ana)
    _wait(lab, clock, ana, 60)
    assert lab.access.view("twin", ana).access.role == "watcher"  # the turn ended on time


def test_a_scripts_turn_is_extended_for_as_long_as_nobody_waits(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = make_lab(control_time_limit=300, idle_limit=None)
    ana, ben = _person(lab, "ana"), _person(lab, "ben")
    script = lab.tokens.resolve(lab.tokens.create(ana, "step test").secret)
    assert script is not None
    lab.access.request_control("twin", script)
    started = clock.now()
    # A 20-minute step test: the client extends in each last minute, as far as it must.
    extensions = 0
    while clock.now() - started < timedelta(minutes=20):
        left = lab.access.view("twin", script).access.time_left
        assert left is not None, f"the turn was cut after {clock.now() - started}"
        _wait(lab, clock, script, max(left - EXTEND_WINDOW + 10, 0))
        lab.access.extend_own("twin", script)
        extensions += 1
    assert extensions > MAX_TURN_EXTENSIONS  # a browser's turn would have ended long ago
    assert lab.access.view("twin", script).access.role == "controller"
    # Once someone waits, the script's turn is bounded as anyone's.
    lab.access.request_control("twin", ben)
    assert lab.access.view("twin", script).access.can_extend is False
    with pytest.raises(TurnExtensionRefusedError, match="someone is waiting"):
        lab.access.extend_own("twin", script)


def test_nobody_extends_while_someone_waits_or_without_control(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = make_lab(control_time_limit=120, idle_limit=None)
    ana, ben = _person(lab, "ana"), _person(lab, "ben")
    lab.access.request_control("twin", ana)
    lab.access.request_control("twin", ben)
    _wait(lab, clock, ana, 70, ben)
    assert lab.access.view("twin", ana).access.can_extend is False
    with pytest.raises(TurnExtensionRefusedError, match="someone is waiting"):
        lab.access.extend_own("twin", ana)
    with pytest.raises(ConflictError, match="you do not control"):
        lab.access.extend_own("twin", ben)
    assert lab.access.view("twin", ben).access.can_extend is False
    lab.access.release("twin", ben)  # the queue is empty again
    assert lab.access.extend_own("twin", ana).access.time_left == pytest.approx(50 + 120)


def test_the_endpoint_answers_in_the_readers_language(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = make_lab(control_time_limit=120, idle_limit=None)
    lab.users.add("ana", PASSWORD, "student")
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with TestClient(app) as ana:
        ana.post("/api/session", json={"username": "ana", "password": PASSWORD})
        ana.post("/api/rigs/twin/control")
        refused = ana.post("/api/rigs/twin/control/more-time", headers={"Accept-Language": "pt-BR"})
        assert refused.status_code == 409
        assert refused.json()["code"] == "extend_refused"
        assert refused.json()["message"] == "Sua vez não pode ser prolongada agora."
        for _ in range(9):
            clock.advance(10)
            ana.post("/api/rigs/twin/heartbeat")
        access = ana.get("/api/rigs/twin").json()["access"]
        assert (access["canExtend"], access["timeLeft"]) == (True, 30.0)
        granted = ana.post("/api/rigs/twin/control/more-time")
        assert granted.status_code == 200
        assert granted.json()["access"]["timeLeft"] == 150.0


def test_a_script_cut_because_someone_waits_is_told_why_by_its_heartbeat_and_its_next_input(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = make_lab(control_time_limit=300, idle_limit=None)
    ana, ben = _person(lab, "ana"), _person(lab, "ben")
    script = lab.tokens.resolve(lab.tokens.create(ana, "step test").secret)
    assert script is not None
    lab.access.request_control("twin", script)
    assert lab.access.heartbeat("twin", script).access.turn_ended is None  # still its turn
    lab.access.request_control("twin", ben)
    _wait(lab, clock, script, 310, ben)
    access = lab.access.heartbeat("twin", script).access
    assert (access.role, access.controller) == ("watcher", "ben")
    assert access.turn_ended is not None
    assert access.turn_ended.startswith("its time limit ran out")
    assert "only while nobody waits" in access.turn_ended
    with pytest.raises(AccessDeniedError, match="your last turn at it ended: its time limit ran"):
        lab.access.record_input("twin", script, 10.0)
    # A teacher's kick is named with the teacher.
    tina = lab.users.add("tina", PASSWORD, "teacher")
    lab.access.kick("twin", Principal(tina.id, tina.username, tina.role))
    assert lab.access.heartbeat("twin", ben).access.turn_ended == "a teacher (tina) ended it"


@pytest.mark.parametrize(
    ("language", "said"),
    [("pt-BR", "um professor (tina) a encerrou"), ("es", "un profesor (tina) lo terminó")],
)
def test_the_heartbeat_says_how_the_turn_ended_in_the_requests_language(
    make_lab: LabFactory, language: str, said: str
) -> None:
    lab = make_lab(control_time_limit=120, idle_limit=None)
    lab.users.add("ana", PASSWORD, "student")
    tina = lab.users.add("tina", PASSWORD, "teacher")
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    with TestClient(app) as ana:
        ana.post("/api/session", json={"username": "ana", "password": PASSWORD})
        assert ana.post("/api/rigs/twin/control").status_code == 200
        lab.access.kick("twin", Principal(tina.id, tina.username, tina.role))
        asked = {"Accept-Language": language}
        access = ana.post("/api/rigs/twin/heartbeat", headers=asked).json()["access"]
        assert access["turnEnded"] == said
        # Without a language the answer is English, as before.
        plain = ana.post("/api/rigs/twin/heartbeat").json()["access"]
        assert plain["turnEnded"] == "a teacher (tina) ended it"
