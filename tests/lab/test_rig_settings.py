"""Teacher settings in the database: the API, the first values, caps, when a change applies.

SQLite (the ``database_url`` fixture); the lab's clock is manual.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime, timedelta

import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.lab.access.rules import TurnRules, TurnState, Waiting, next_state
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import CooldownPolicy, RigConfig
from thermolab.lab.config.teacher_settings import SETTINGS, TEACHER_SETTINGS
from thermolab.lab.db.models import PowerState
from thermolab.lab.service import Lab

from .conftest import PASSWORD, LabFactory
from .test_runs import StepClock, person, until

# On SQLite alone: settings rules; their storage is test_db and the upgrade ladder on both
# (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only

Clients = Callable[..., TestClient]


@pytest.fixture
def teacher(lab: Lab, app_client: Clients) -> TestClient:
    lab.users.add("tina", PASSWORD, "teacher", admin=True)
    return app_client("tina")


def _values(body: dict[str, object]) -> dict[str, object]:
    settings_ = body["settings"]
    assert isinstance(settings_, list)
    return {s["name"]: s["value"] for s in settings_}


def test_a_teacher_reads_and_changes_the_settings_a_student_cannot(
    lab: Lab, teacher: TestClient, app_client: Clients
) -> None:
    got = teacher.get("/api/rigs/twin/settings")
    assert got.status_code == 200, got.text
    body = got.json()
    # Every declared setting, in declaration order, with the file's first values.
    assert [s["name"] for s in body["settings"]] == [s.name for s in TEACHER_SETTINGS]
    assert _values(body)["control_time_limit"] == 300.0
    assert (body["version"], body["updatedBy"], body["inputUnit"]) == (1, None, "V")
    by_name = {s["name"]: s for s in body["settings"]}
    assert (by_name["control_time_limit"]["minimum"], by_name["control_time_limit"]["maximum"]) == (
        10.0,
        86400.0,
    )
    # The cool-down input's range is the rig's input range.
    assert (by_name["cooldown_input"]["minimum"], by_name["cooldown_input"]["maximum"]) == (
        -10.0,
        10.0,
    )
    assert by_name["cooldown_mode"]["choices"] == ["none", "ambient"]

    lab.users.add("sam", PASSWORD, "student")
    student = app_client("sam")
    for response in (
        student.get("/api/rigs/twin/settings"),
        student.put("/api/rigs/twin/settings", json={"version": 1, "values": {}}),
    ):
        assert response.status_code == 403
        assert response.json()["code"] == "access_denied"

    saved = teacher.put(
        "/api/rigs/twin/settings",
        json={
            "version": 1,
            "values": {"control_time_limit": 90, "idle_limit": None, "cooldown_mode": "ambient"},
        },
    )
    assert saved.status_code == 200, saved.text
    assert (saved.json()["version"], saved.json()["updatedBy"]) == (2, "tina")
    values = _values(saved.json())
    assert (values["control_time_limit"], values["idle_limit"], values["cooldown_mode"]) == (
        90.0,
        None,
        "ambient",
    )
    # In force at once: the rig's published limits (everyone's view) and the lab's rig.
    rig = student.get("/api/rigs/twin").json()
    assert rig["limits"]["controlTimeLimit"] == 90.0
    assert rig["limits"]["idleLimit"] is None
    assert lab.config.rig("twin").cooldown.mode == "ambient"
    assert lab.config.rig("other").control_time_limit == 300.0  # only that rig


def test_bad_values_are_refused_with_the_range_and_change_nothing(
    lab: Lab, teacher: TestClient
) -> None:
    too_short = teacher.put(
        "/api/rigs/twin/settings",
        json={"version": 1, "values": {"control_time_limit": 5, "max_run_seconds": 600}},
    )
    assert too_short.status_code == 422
    body = too_short.json()
    assert body["code"] == "setting_out_of_range"
    assert "allowed: 10 to 86400 s" in body["detail"]
    assert body["errors"][0]["loc"] == ["body", "values", "control_time_limit"]
    assert body["message"]  # the code's sentence
    # Outside the rig's input range.
    fan = teacher.put(
        "/api/rigs/twin/settings", json={"version": 1, "values": {"cooldown_input": -11}}
    )
    assert fan.status_code == 422
    assert "allowed: -10 to 10" in fan.json()["detail"]
    # Not a setting, not a choice, not a number: the schema's refusal.
    for values in ({"speed": 3}, {"cooldown_mode": "cold"}, {"idle_limit": "long"}):
        response = teacher.put("/api/rigs/twin/settings", json={"version": 1, "values": values})
        assert response.status_code == 422, values
        assert response.json()["code"] == "invalid_request"
    unknown = teacher.get("/api/rigs/nope/settings")
    assert unknown.status_code == 404
    # Nothing was saved.
    after = teacher.get("/api/rigs/twin/settings").json()
    assert after["version"] == 1
    assert lab.config.rig("twin").max_run_seconds == 3600.0


def test_a_save_based_on_an_old_version_is_a_conflict(lab: Lab, teacher: TestClient) -> None:
    first = teacher.put(
        "/api/rigs/twin/settings", json={"version": 1, "values": {"control_time_limit": 120}}
    )
    assert first.status_code == 200
    late = teacher.put(
        "/api/rigs/twin/settings", json={"version": 1, "values": {"control_time_limit": 200}}
    )
    assert late.status_code == 409
    assert late.json()["code"] == "settings_changed"
    assert lab.config.rig("twin").control_time_limit == 120.0


def test_the_file_gives_first_values_and_caps_then_the_database_wins(
    make_lab: LabFactory,
) -> None:
    caps = (("max_run_seconds", 600.0),)
    lab = make_lab(control_time_limit=120.0, caps=caps)
    tina = person(lab, "tina", "admin")
    assert lab.settings.get("twin", tina).values["control_time_limit"] == 120.0
    # The technician's cap bounds the teacher.
    assert lab.settings.get("twin", tina).ranges["max_run_seconds"] == (10.0, 600.0)
    with pytest.raises(ValueError, match="allowed: 10 to 600 s"):
        lab.settings.update("twin", tina, {"max_run_seconds": 700.0}, 1)
    lab.settings.update("twin", tina, {"control_time_limit": 240.0}, 1)
    # A second start on the same database, with another first value: the database's wins.
    again = make_lab(control_time_limit=60.0, caps=caps)
    assert again.config.rig("twin").control_time_limit == 240.0
    # A cap lowered in the file lowers a stored value above it.
    lab.settings.update("twin", tina, {"max_run_seconds": 500.0}, 2)
    lower = make_lab(caps=(("max_run_seconds", 300.0),))
    assert lower.config.rig("twin").max_run_seconds == 300.0


def test_a_changed_turn_limit_applies_to_the_next_turn_and_never_cuts_the_run(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    step_clock = StepClock()

    def opener(rig: RigConfig) -> object:
        from thermolab.rigs import TwinRig

        return TwinRig("paper", clock=step_clock)

    try:
        lab = make_lab(opener=opener, control_time_limit=300.0)
        tina, ana, ben = person(lab, "tina", "admin"), person(lab, "ana"), person(lab, "ben")
        lab.access.request_control("twin", ana)
        from thermolab.lab.runs import RunRequest

        run = lab.runs.start("twin", ana, RunRequest(dt=1.0, samples=200, signal="step:0:4@1"))
        lab.access.request_control("twin", ben)
        # The teacher cuts the turn limit to 60 s while ana's 200-s run goes.
        lab.settings.update("twin", tina, {"control_time_limit": 60.0}, 1)
        view = lab.access.view("twin", ana).access
        assert view.time_left == pytest.approx(300.0)  # her turn keeps its deadline
        for t in range(10, 201, 10):
            clock.advance(10)
            lab.access.heartbeat("twin", ana)
            lab.access.heartbeat("twin", ben)
            lab.sweep()
            assert lab.access.view("twin", ana).access.role == "controller"
            step_clock.allow(min(t, 199))
            until(lambda t=t: lab.runs.get(run.id, ana).samples_taken >= min(t, 199) + 1)
        lab.runs.wait("twin", timeout=30)
        assert lab.runs.get(run.id, ana).status == "finished"
        lab.access.release("twin", ana)
        # Ben's turn is the first under the new limit.
        assert lab.access.view("twin", ben).access.time_left == pytest.approx(60.0)
    finally:
        step_clock.allow(math.inf)


# -- the rule itself, for any sequence of changes (Hypothesis) -------------------------------

T0 = datetime(2026, 1, 1, tzinfo=UTC)
_RULES = TurnRules(timedelta(hours=10), 300.0, None, 60.0, CooldownPolicy())


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(10.0, 1000.0),  # the limit the teacher sets now
            st.floats(0.0, 400.0),  # seconds until the next look at the rig
            st.booleans(),  # a run is going during that time
        ),
        min_size=1,
        max_size=25,
    )
)
def test_every_turn_lasts_the_limit_in_force_when_it_started(
    steps: list[tuple[float, float, bool]],
) -> None:
    """A turn's deadline is fixed when it starts; a going run is never cut by a limit."""

    def look(state: TurnState, rules: TurnRules, now: datetime) -> TurnState:
        after = next_state(state, rules, now, None)
        if after.turn is not None and after.turn != state.turn:
            # A new turn: the limit in force now.
            assert after.turn.deadline - after.turn.started_at == timedelta(
                seconds=rules.control_time_limit
            )
        elif after.turn is not None and state.turn is not None:
            assert after.turn.deadline == state.turn.deadline  # a going turn keeps its end
        if state.run_active and state.turn is not None:
            assert after.turn == state.turn  # the run covers the turn, whatever the limit now
        return after

    now = T0
    state = TurnState(True, False, PowerState.ON, False, None, now, 20.0, None, (), False)
    for limit, wait, running in steps:
        rules = replace(_RULES, control_time_limit=limit)
        # Someone always waits, so a free rig starts a turn at once.
        state = replace(state, queue=state.queue or (Waiting(1, now),), run_active=running)
        state = look(state, rules, now)
        now += timedelta(seconds=wait)
        state = look(state, rules, now)


def test_every_setting_has_a_declared_range_or_choices() -> None:
    for setting in TEACHER_SETTINGS:
        assert SETTINGS[setting.name] is setting
        if setting.type == "choice":
            assert setting.choices
            assert setting.default in setting.choices
        elif setting.minimum is not None:
            assert setting.maximum is not None
            assert setting.minimum <= setting.maximum
            assert setting.default is None or setting.minimum <= setting.default <= setting.maximum
