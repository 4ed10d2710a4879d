"""Bookings: the calendar, clashes refused atomically, slots in the turn rules (both databases)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from datetime import UTC, datetime, timedelta

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from thermolab.errors import BookingClashError, RigBookedError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.db.booking_models import Booking
from thermolab.lab.db.models import ControlSession, QueueEntry
from thermolab.lab.service import Lab

from .conftest import PASSWORD, LabFactory

Clients = Callable[..., TestClient]
T0 = datetime(2026, 1, 1, tzinfo=UTC)


def iso(minutes: float) -> str:
    return (T0 + timedelta(minutes=minutes)).isoformat().replace("+00:00", "Z")


def person(lab: Lab, name: str, role: str = "student") -> Principal:
    info = lab.users.add(name, PASSWORD, role)
    return Principal(info.id, info.username, info.role)


def course(lab: Lab, teacher: str, name: str, students: list[str]) -> None:
    lab.courses.create(name, f"Course {name}", teacher)
    roster = "username,display_name\n" + "".join(f"{s},{s.title()}\n" for s in students)
    lab.courses.import_class_list(name, roster.encode())


@pytest.fixture
def lab(make_lab: LabFactory) -> Lab:
    """Turns long enough to reach a slot, no idle limit."""
    return make_lab(control_time_limit=3600.0, idle_limit=None)


@pytest.fixture
def school(lab: Lab) -> dict[str, Principal]:
    """Tina teaches ctrl1 (ana, ben); Theo teaches ctrl2 (carla)."""
    people = {
        "tina": person(lab, "tina", "teacher"),
        "theo": person(lab, "theo", "teacher"),
        **{name: person(lab, name) for name in ("ana", "ben", "carla")},
    }
    course(lab, "tina", "ctrl1", ["ana", "ben"])
    course(lab, "theo", "ctrl2", ["carla"])
    return people


def test_a_teacher_books_edits_and_cancels_and_clashes_name_the_slot(
    lab: Lab, school: dict[str, Principal], app_client: Clients
) -> None:
    tina = app_client("tina")
    theo = app_client("theo")
    booked = tina.post(
        "/api/bookings",
        json={
            "course": "ctrl1",
            "rigs": ["twin", "other"],
            "startsAt": iso(60),
            "endsAt": iso(120),
        },
    )
    assert booked.status_code == 201, booked.text
    slot = booked.json()
    assert (slot["course"], slot["rigs"], slot["own"]) == ("ctrl1", ["other", "twin"], True)
    # In UTC, whatever zone the request was written in.
    assert slot["startsAt"].startswith("2026-01-01T01:00:00")
    # Overlapping on one shared rig, written in another zone: refused, naming the slot.
    clash = theo.post(
        "/api/bookings",
        json={
            "course": "ctrl2",
            "rigs": ["twin"],
            "startsAt": "2025-12-31T22:30:00-03:00",  # 01:30 UTC
            "endsAt": "2025-12-31T23:30:00-03:00",
        },
    )
    assert clash.status_code == 409, clash.text
    body = clash.json()
    assert body["code"] == "booking_clash"
    assert body["slot"]["course"] == "ctrl1"
    assert body["slot"]["rigs"] == ["twin"]
    assert body["slot"]["startsAt"].startswith("2026-01-01T01:00")
    assert "ctrl1" in body["detail"]
    # Touching (end == start) is not overlapping; another rig at the same time neither.
    after = {"course": "ctrl2", "rigs": ["twin"], "startsAt": iso(120), "endsAt": iso(180)}
    assert theo.post("/api/bookings", json=after).status_code == 201
    # Editing the first into the second's time clashes; moving it elsewhere does not.
    moved = {"rigs": ["twin"], "startsAt": iso(150), "endsAt": iso(200)}
    refused = tina.put(f"/api/bookings/{slot['id']}", json=moved)
    assert refused.status_code == 409
    assert refused.json()["slot"]["course"] == "ctrl2"
    moved = {"rigs": ["twin"], "startsAt": iso(30), "endsAt": iso(90), "note": "lab 2"}
    edited = tina.put(f"/api/bookings/{slot['id']}", json=moved)
    assert edited.status_code == 200, edited.text
    assert (edited.json()["rigs"], edited.json()["note"]) == (["twin"], "lab 2")
    # The calendar: teachers see every course; a student sees other courses only as reserved.
    window = {"from": iso(0), "to": iso(24 * 60)}
    assert [b["course"] for b in tina.get("/api/bookings", params=window).json()] == [
        "ctrl1",
        "ctrl2",
    ]
    ana = app_client("ana")
    seen = ana.get("/api/bookings", params=window).json()
    assert [(b["course"], b["own"], b["note"]) for b in seen] == [
        ("ctrl1", True, "lab 2"),
        (None, False, ""),
    ]
    # Students may not book; cancelling frees the time.
    assert ana.post("/api/bookings", json=after | {"course": "ctrl1"}).status_code == 403
    assert tina.delete(f"/api/bookings/{slot['id']}").status_code == 204
    assert tina.delete(f"/api/bookings/{slot['id']}").status_code == 404
    assert len(ana.get("/api/bookings", params=window).json()) == 1


def test_only_the_courses_teachers_book_move_or_cancel_its_slots(
    school: dict[str, Principal], app_client: Clients
) -> None:
    tina = app_client("tina")
    theo = app_client("theo")  # teaches ctrl2, not ctrl1
    slot = {"course": "ctrl1", "rigs": ["twin"], "startsAt": iso(60), "endsAt": iso(120)}
    refused = theo.post("/api/bookings", json=slot)
    assert refused.status_code == 403, refused.text
    assert refused.json()["code"] == "access_denied"
    assert "ctrl1" in refused.json()["detail"]
    booked = tina.post("/api/bookings", json=slot)
    assert booked.status_code == 201, booked.text
    slot_id = booked.json()["id"]
    moved = {"rigs": ["twin"], "startsAt": iso(200), "endsAt": iso(260)}
    assert theo.put(f"/api/bookings/{slot_id}", json=moved).status_code == 403
    assert theo.delete(f"/api/bookings/{slot_id}").status_code == 403
    window = {"from": iso(0), "to": iso(24 * 60)}
    kept = tina.get("/api/bookings", params=window).json()
    assert [(b["id"], b["startsAt"][:16]) for b in kept] == [(slot_id, "2026-01-01T01:00")]
    assert tina.delete(f"/api/bookings/{slot_id}").status_code == 204


@pytest.mark.parametrize(
    ("changes", "code"),
    [
        ({"startsAt": "2026-01-01T02:00:00"}, "invalid_request"),  # no zone
        ({"endsAt": iso(30)}, "slot_ends_before_start"),
        ({"endsAt": iso(60 + 25 * 60)}, "slot_too_long"),  # longer than a day, not said
        ({"startsAt": iso(-120), "endsAt": iso(-60)}, "invalid_parameter"),  # over already
        ({"rigs": []}, "invalid_request"),
        ({"rigs": ["nope"]}, "not_found"),
        ({"course": "nope"}, "not_found"),
    ],
)
def test_bad_bookings_get_a_clear_4xx(
    school: dict[str, Principal], app_client: Clients, changes: dict[str, object], code: str
) -> None:
    good = {"course": "ctrl1", "rigs": ["twin"], "startsAt": iso(60), "endsAt": iso(120)}
    answer = app_client("tina").post("/api/bookings", json=good | changes)
    assert answer.status_code in (404, 422), answer.text
    assert answer.json()["code"] == code


def test_a_calendar_window_is_bounded_and_well_formed(
    school: dict[str, Principal], app_client: Clients
) -> None:
    ana = app_client("ana")
    assert ana.get("/api/bookings", params={"from": iso(0), "to": iso(0)}).status_code == 422
    far = {"from": iso(0), "to": iso(63 * 24 * 60)}
    assert ana.get("/api/bookings", params=far).json()["code"] == "invalid_parameter"
    bad = ana.get("/api/bookings", params={"from": "2026-13-01T00:00Z", "to": iso(10)})
    assert bad.status_code == 422
    assert ana.get("/api/bookings", params={"from": "yesterday", "to": iso(10)}).status_code == 422


def test_two_teachers_booking_overlapping_slots_at_once_exactly_one_wins(
    lab: Lab, school: dict[str, Principal]
) -> None:
    barrier = threading.Barrier(8)
    outcomes: list[BaseException | None] = []
    lock = threading.Lock()

    def book(teacher: str, name: str, offset: int) -> None:
        barrier.wait()
        try:
            lab.bookings.create(
                school[teacher],
                name,
                ["other", "twin"] if offset % 2 else ["twin"],
                T0 + timedelta(minutes=60 + offset),
                T0 + timedelta(minutes=120 + offset),
            )
            result: BaseException | None = None
        except BookingClashError as exc:
            result = exc
        with lock:
            outcomes.append(result)

    threads = [
        threading.Thread(target=book, args=(t, c, i))
        for i, (t, c) in enumerate([("tina", "ctrl1"), ("theo", "ctrl2")] * 4)
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    assert len(outcomes) == 8
    assert sum(o is None for o in outcomes) == 1
    with lab.db.read() as session:
        assert session.scalar(select(func.count()).select_from(Booking)) == 1


@pytest.mark.slow
def test_a_slot_hands_the_rig_to_its_course_and_refuses_outsiders(
    lab: Lab, clock: ManualClock, school: dict[str, Principal], app_client: Clients
) -> None:
    ana, ben, carla = school["ana"], school["ben"], school["carla"]
    # Before the slot carla (ctrl2) controls the twin; theo (not in ctrl1) and ana wait.
    lab.access.request_control("twin", carla)
    lab.access.request_control("twin", school["theo"])
    lab.access.request_control("twin", ana)
    lab.bookings.create(
        school["tina"], "ctrl1", ["twin"], T0 + timedelta(minutes=10), T0 + timedelta(minutes=70)
    )
    chance = app_client("carla").get("/api/rigs/twin/next-chance").json()
    assert chance["bookedNow"] is None
    assert chance["freeFrom"] is None
    assert chance["nextOwn"] is None
    # The slot begins: carla's turn ends (reason booked), theo's place is dropped, ana controls.
    for _ in range(120):  # the clients keep in touch while the time passes
        clock.advance(5.0)
        for who in (carla, school["theo"], ana):
            lab.access.heartbeat("twin", who)
    lab.sweep()
    snap = lab.access.snapshot("twin")
    assert snap.controller is not None
    assert snap.controller.user_id == ana.user_id
    with lab.db.read() as session:
        ended = session.scalars(
            select(ControlSession).where(ControlSession.user_id == carla.user_id)
        ).one()
        left = session.scalars(
            select(QueueEntry).where(QueueEntry.user_id == school["theo"].user_id)
        ).one()
    assert ended.end_reason == "booked"
    assert ended.ended_at == T0 + timedelta(minutes=10)
    assert left.leave_reason == "booked"
    # Inside the slot: an outsider is refused with the slot named; the course queues as usual.
    with pytest.raises(RigBookedError, match="booked for another course's slot"):
        lab.access.request_control("twin", carla)
    refused = app_client("carla").post("/api/rigs/twin/control")
    assert refused.status_code == 409
    assert refused.json()["code"] == "rig_booked"
    assert refused.json()["slot"]["endsAt"].startswith("2026-01-01T01:10")
    view = lab.access.request_control("twin", ben)
    assert view.access.queue_position == 1
    chance = app_client("carla").get("/api/rigs/twin/next-chance").json()
    assert chance["bookedNow"]["course"] is None
    assert chance["freeFrom"].startswith("2026-01-01T01:10")
    mine = app_client("ben").get("/api/rigs/twin/next-chance").json()
    assert mine["bookedNow"]["course"] == "ctrl1"
    assert mine["freeFrom"] is None
    # The other rig is not booked: carla may use it.
    assert lab.access.request_control("other", carla).access.role == "controller"
    # After the slot the queue works as before: carla may queue again.
    clock.advance(60 * 60.0)
    lab.sweep()
    assert lab.access.request_control("twin", carla).access.role in ("queued", "controller")


def test_a_turn_a_slot_ended_is_in_the_history_with_its_reason(
    lab: Lab, clock: ManualClock, school: dict[str, Principal], app_client: Clients
) -> None:
    lab.access.request_control("twin", school["carla"])
    lab.bookings.create(school["tina"], "ctrl1", ["twin"], T0, T0 + timedelta(hours=1))
    lab.sweep()
    history = app_client("carla").get("/api/rigs/twin/control-sessions")
    assert history.status_code == 200, history.text
    assert history.json()[0]["endReason"] == "booked"
