"""Limits per course: a course's values in force on its booked rigs during its slots.

The pure rule (a Hypothesis property on the transition table) and the API with
the turn rules on a real lab (both databases, the ``lab`` fixture's).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime, timedelta

import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.errors import InvalidParameterError, RigBookedError
from thermolab.lab.access.rules import Slot, TurnRules, TurnState, Waiting, current_slot, next_state
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import CooldownPolicy
from thermolab.lab.db.models import PowerState
from thermolab.lab.runs.request import RunRequest
from thermolab.lab.service import Lab
from thermolab.rigs import TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory

Clients = Callable[..., TestClient]
T0 = datetime(2026, 1, 1, tzinfo=UTC)
RIG_LIMIT = 300.0
CAP = 1200.0


def at(seconds: float) -> datetime:
    return T0 + timedelta(seconds=seconds)


def rig_rules() -> TurnRules:
    return TurnRules(
        timedelta(seconds=15),
        RIG_LIMIT,
        None,
        60.0,
        CooldownPolicy(),
        (("control_time_limit", CAP),),
    )


def in_force(slots: tuple[Slot, ...], when: datetime) -> float:
    """The turn limit in force at ``when``: the course's (capped) in its slot, else the rig's."""
    slot = current_slot(slots, when)
    if slot is None:
        return RIG_LIMIT
    given_ = dict(slot.limits).get("control_time_limit")
    return RIG_LIMIT if given_ is None else min(float(given_), CAP)


@settings(max_examples=150, deadline=None)
@given(
    slots=st.lists(
        st.tuples(
            st.integers(1, 100),  # gap before the slot, s
            st.integers(1, 400),  # its length
            st.one_of(st.none(), st.integers(10, 2000)),  # the course's turn limit
        ),
        max_size=3,
    ),
    steps=st.lists(
        st.tuples(st.integers(1, 300), st.booleans(), st.booleans()), min_size=1, max_size=25
    ),
)
def test_a_turns_limit_is_the_one_in_force_when_it_started(
    slots: list[tuple[int, int, int | None]], steps: list[tuple[int, bool, bool]]
) -> None:
    """Whatever the slots and the moments the rules are applied, every turn's deadline is its
    start plus the limit in force at that start, and a turn going keeps its deadline."""
    # Users 1 and 2 belong to every course, so slots hand them turns rather than refuse them.
    booked: list[Slot] = []
    start = 0
    for i, (gap, length, limit) in enumerate(slots):
        start += gap
        limits = () if limit is None else (("control_time_limit", float(limit)),)
        booked.append(Slot(i + 1, i + 1, at(start), at(start + length), frozenset({1, 2}), limits))
        start += length
    state = TurnState(True, False, PowerState.ON, False, None, T0, 20.0, None, (), False)
    state = replace(state, slots=tuple(booked))
    now = T0
    for advance, ask, release in steps:
        now += timedelta(seconds=advance)
        if ask:  # both keep asking (their heartbeats are fresh)
            state = replace(state, queue=tuple(Waiting(u, now) for u in (1, 2)))
            if state.turn is not None:
                state = replace(
                    state,
                    queue=tuple(w for w in state.queue if w.user_id != state.turn.user_id),
                    turn=replace(state.turn, last_heartbeat_at=now),
                )
        if release and state.turn is not None:
            state = replace(state, turn=replace(state.turn, deadline=now))  # ends at this step
        before = state.turn
        state = next_state(state, rig_rules(), now, None)
        after = state.turn
        if after is None:
            continue
        if before is not None and after.started_at == before.started_at:
            assert after.deadline == before.deadline, "a turn going changed its deadline"
        else:
            expected = in_force(state.slots, after.started_at)
            assert after.deadline == after.started_at + timedelta(seconds=expected)


def test_outside_slots_and_for_settings_left_out_the_rigs_values_apply() -> None:
    slot = Slot(1, 1, at(0), at(60), frozenset({1}), (("idle_limit", None),))
    rules = rig_rules()
    during = rules.during(slot)
    assert (during.control_time_limit, during.idle_limit) == (RIG_LIMIT, None)
    assert rules.during(None) is rules
    capped = rules.during(replace(slot, limits=(("control_time_limit", 5000.0),)))
    assert capped.control_time_limit == CAP


# -- the API and the rules on a real lab ------------------------------------------------------


def person(lab: Lab, name: str, role: str = "student") -> Principal:
    info = lab.users.add(name, PASSWORD, role)
    return Principal(info.id, info.username, info.role)


@pytest.fixture
def lab(make_lab: LabFactory) -> Lab:
    return make_lab(
        control_time_limit=300.0,
        idle_limit=120.0,
        max_run_seconds=600.0,
        opener=lambda rig: TwinRig("paper", clock=VirtualClock()),
    )


@pytest.fixture
def school(lab: Lab) -> dict[str, Principal]:
    """Tina teaches ctrl1 (ana); Theo teaches nothing; Sam is in no course."""
    people = {
        "tina": person(lab, "tina", "teacher"),
        "theo": person(lab, "theo", "teacher"),
        "ana": person(lab, "ana"),
        "sam": person(lab, "sam"),
    }
    lab.courses.create("ctrl1", "Control 1", "tina")
    lab.courses.import_class_list("ctrl1", b"username,display_name\nana,Ana\n")
    return people


def test_a_teacher_of_the_course_reads_and_replaces_its_limits(
    school: dict[str, Principal], app_client: Clients
) -> None:
    tina = app_client("tina")
    got = tina.get("/api/courses/ctrl1/settings")
    assert got.status_code == 200, got.text
    body = got.json()
    assert body["version"] == 0
    assert [s["name"] for s in body["settings"]] == [
        "control_time_limit",
        "idle_limit",
        "max_run_seconds",
    ]
    assert not any(s["overridden"] for s in body["settings"])
    assert "slot" in body["rule"]
    saved = tina.put(
        "/api/courses/ctrl1/settings",
        json={"version": 0, "values": {"control_time_limit": 900, "idle_limit": None}},
    )
    assert saved.status_code == 200, saved.text
    by_name = {s["name"]: s for s in saved.json()["settings"]}
    assert (by_name["control_time_limit"]["value"], by_name["idle_limit"]["overridden"]) == (
        900.0,
        True,
    )
    assert by_name["max_run_seconds"]["overridden"] is False
    assert (saved.json()["version"], saved.json()["updatedBy"]) == (1, "tina")
    # A save based on the old version: 409; out of range: 422 naming the range; nothing saved.
    stale = tina.put("/api/courses/ctrl1/settings", json={"version": 0, "values": {}})
    assert (stale.status_code, stale.json()["code"]) == (409, "settings_changed")
    wide = tina.put(
        "/api/courses/ctrl1/settings", json={"version": 1, "values": {"control_time_limit": 5}}
    )
    assert (wide.status_code, wide.json()["code"]) == (422, "setting_out_of_range")
    assert "10 to 86400" in wide.json()["detail"]
    unknown = tina.put(
        "/api/courses/ctrl1/settings", json={"version": 1, "values": {"cooldown_mode": "none"}}
    )
    assert unknown.status_code == 422
    assert tina.get("/api/courses/ctrl1/settings").json()["version"] == 1
    # A student, and a teacher not in the course: 403; an unknown course: 404.
    for who in ("ana", "theo"):
        client = app_client(who)
        for answer in (
            client.get("/api/courses/ctrl1/settings"),
            client.put("/api/courses/ctrl1/settings", json={"version": 1, "values": {}}),
        ):
            assert (answer.status_code, answer.json()["code"]) == (403, "access_denied")
    assert tina.get("/api/courses/nope/settings").status_code == 404
    # Without a login: 401.
    anyone = app_client()
    assert anyone.get("/api/courses/ctrl1/settings").status_code == 401
    assert anyone.put("/api/courses/ctrl1/settings", json={}).status_code == 401


def test_during_the_slot_the_courses_limits_apply_and_a_turn_keeps_its_own(
    lab: Lab, clock: ManualClock, school: dict[str, Principal]
) -> None:
    ana, sam, tina = school["ana"], school["sam"], school["tina"]
    lab.course_settings.update(
        "ctrl1", tina, {"control_time_limit": 900.0, "idle_limit": None, "max_run_seconds": 60}, 0
    )
    # Before the slot: the rig's limits.
    lab.access.request_control("twin", ana)
    control = lab.access.snapshot("twin").controller
    assert control is not None
    assert (control.deadline - control.started_at).total_seconds() == 300.0
    view = lab.access.view("twin", ana)
    assert view.access.idle_time_left == 120.0
    lab.access.release("twin", ana)
    start = clock.now() + timedelta(seconds=30)
    lab.bookings.create(tina, "ctrl1", ["twin"], start, start + timedelta(hours=1))
    clock.advance(40.0)
    lab.access.request_control("twin", ana)
    control = lab.access.snapshot("twin").controller
    assert control is not None
    assert (control.deadline - control.started_at).total_seconds() == 900.0
    seen = lab.access.view("twin", ana)
    assert seen.access.idle_time_left is None  # the course's: never
    # The rig's page shows the limits in force (GET /api/rigs/{rig}'s ``limits``).
    assert (seen.config.control_time_limit, seen.config.idle_limit) == (900.0, None)
    assert seen.config.max_run_seconds == 60.0
    # The longest run: the course's 60 s, in force at START.
    with pytest.raises(InvalidParameterError, match=r"longer than rig 'twin' allows \(60 s\)"):
        lab.runs.start("twin", ana, RunRequest(dt=1.0, samples=120))
    # In its last minute the turn may be extended: the ceiling counts the course's 900 s
    # (with the rig's 300 s it would be refused).
    for _ in range(172):
        clock.advance(5.0)
        lab.access.heartbeat("twin", ana)
    assert lab.access.view("twin", ana).access.can_extend
    lab.access.extend_own("twin", ana)
    extended = lab.access.snapshot("twin").controller
    assert extended is not None
    assert extended.deadline == control.deadline + timedelta(seconds=120)
    # A change now does not move the turn going (its deadline was set when it started).
    lab.course_settings.update("ctrl1", tina, {"control_time_limit": 60.0, "idle_limit": None}, 1)
    for _ in range(20):  # ana keeps in touch for 100 s, past the new 60 s limit
        clock.advance(5.0)
        lab.access.heartbeat("twin", ana)
    lab.sweep()
    kept = lab.access.snapshot("twin").controller
    assert kept is not None
    assert (kept.user_id, kept.deadline) == (ana.user_id, extended.deadline)
    # The next turn gets the new value: ana hands over to herself again.
    lab.access.release("twin", ana)
    lab.access.request_control("twin", ana)
    again = lab.access.snapshot("twin").controller
    assert again is not None
    assert (again.deadline - again.started_at).total_seconds() == 60.0
    # Someone outside the course is still refused during the slot.
    with pytest.raises(RigBookedError):
        lab.access.request_control("twin", sam)


def test_a_slot_that_ends_while_a_start_is_decided_no_longer_lengthens_that_run(
    lab: Lab, clock: ManualClock, school: dict[str, Principal]
) -> None:
    # The course's longest run is read in START's own transaction: read before it, a
    # slot ending in between still gave the run the course's 1200 s, not the rig's 600 s.
    ana, tina = school["ana"], school["tina"]
    lab.course_settings.update("ctrl1", tina, {"max_run_seconds": 1200}, 0)
    begins = clock.now() + timedelta(seconds=10)
    lab.bookings.create(tina, "ctrl1", ["twin"], begins, begins + timedelta(minutes=5))
    clock.advance(280.0)  # 10 s of the slot left
    lab.access.request_control("twin", ana)

    def meanwhile(point: str) -> None:
        if point == "start:arrived":
            clock.advance(20.0)  # the slot ends while the START is being decided

    lab.runs.checkpoint = meanwhile
    with pytest.raises(InvalidParameterError, match=r"longer than rig 'twin' allows \(600 s\)"):
        lab.runs.start("twin", ana, RunRequest(dt=1.0, samples=900))
    assert lab.runs.list(ana) == []
    assert lab.access.snapshot("twin").controller is not None  # the refusal ends no turn
