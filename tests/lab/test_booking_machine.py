"""Bookings and turns under any sequence of acts: a Hypothesis state machine on the real lab.

Students of the booked course and outsiders ask for control and release it,
a teacher books and cancels slots (some starting at once, some later, some
clashing), and time passes (the clients keeping in touch, then the lab's
sweep). After every step: at most one controller, and during a slot nobody
outside its course controls the rig or waits for it; an outsider asking
during a slot is refused, a member never is.
"""

from __future__ import annotations

import contextlib
from datetime import timedelta

import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule, run_state_machine_as_test
from sqlalchemy import func, select

from thermolab.errors import BookingClashError, InvalidParameterError, RigBookedError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import AccessPolicy
from thermolab.lab.db.models import ControlSession

from .conftest import PASSWORD, LabFactory

RIG = "twin"
MEMBERS = ("ana", "ben")
OUTSIDERS = ("carla", "dan")


@pytest.mark.slow
def test_no_outsider_controls_or_waits_during_a_slot_whatever_happens(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    # Clients count as gone after 120 s without contact (15 s by default), so time can
    # pass in steps of 100 s: a few transactions a wait instead of 35 rounds of heartbeats.
    lab = make_lab(
        control_time_limit=600.0, idle_limit=None, access=AccessPolicy(client_timeout=120.0)
    )
    people = {}
    for name, role in [("tina", "teacher"), *((n, "student") for n in MEMBERS + OUTSIDERS)]:
        info = lab.users.add(name, PASSWORD, role)
        people[name] = Principal(info.id, info.username, info.role)
    lab.courses.create("inside", "Booked course", "tina")
    roster = "username,display_name\n" + "".join(f"{n},{n.title()}\n" for n in MEMBERS)
    lab.courses.import_class_list("inside", roster.encode())
    tina = people["tina"]
    students = st.sampled_from(MEMBERS + OUTSIDERS)

    def current_slot() -> bool:
        now = clock.now()
        return bool(lab.bookings.calendar(tina, now, now + timedelta(microseconds=1), RIG))

    class Machine(RuleBasedStateMachine):
        def __init__(self) -> None:
            super().__init__()
            # Each example starts from a free rig with no booking.
            now = clock.now()
            for booking in lab.bookings.calendar(
                tina, now - timedelta(days=30), now + timedelta(days=30)
            ):
                lab.bookings.cancel(tina, booking.id)
            for name in MEMBERS + OUTSIDERS:
                lab.access.release(RIG, people[name])
            # Outsiders hold and wait for the rig when the example starts.
            for name in OUTSIDERS:
                lab.access.request_control(RIG, people[name])

        @rule(names=st.lists(students, min_size=1, max_size=3))
        def ask(self, names: list[str]) -> None:
            for name in names:
                booked = current_slot()
                try:
                    lab.access.request_control(RIG, people[name])
                except RigBookedError:
                    assert booked, f"{name} refused outside a slot"
                    assert name in OUTSIDERS, f"{name}, of the course, refused"
                else:
                    assert not (booked and name in OUTSIDERS), f"{name} admitted during a slot"

        @rule(name=students)
        def release(self, name: str) -> None:
            lab.access.release(RIG, people[name])

        @rule(start=st.integers(-120, 300), length=st.integers(60, 1800))
        def book(self, start: int, length: int) -> None:
            begins = clock.now() + timedelta(seconds=start)
            # Overlapping another, or over already: refused, nothing changes.
            with contextlib.suppress(BookingClashError, InvalidParameterError):
                lab.bookings.create(
                    tina, "inside", [RIG], begins, begins + timedelta(seconds=length)
                )

        @rule()
        def cancel(self) -> None:
            now = clock.now()
            for booking in lab.bookings.calendar(tina, now, now + timedelta(days=1), RIG)[:1]:
                lab.bookings.cancel(tina, booking.id)

        @rule(seconds=st.integers(1, 420))
        def wait(self, seconds: int) -> None:
            # The clients keep in touch (every 100 s, under the 120-s timeout) as time
            # passes; 420 s reaches past every slot's start (at most 300 s ahead).
            while seconds > 0:
                step = min(seconds, 100)
                clock.advance(float(step))
                seconds -= step
                for name in MEMBERS + OUTSIDERS:
                    lab.access.heartbeat(RIG, people[name])
            lab.sweep()

        @invariant()
        def one_controller_and_no_outsider_during_a_slot(self) -> None:
            view = lab.access.view(RIG, tina, heartbeat=False)  # settles whatever is due
            assert view is not None
            snap = lab.access.snapshot(RIG)
            with lab.db.read() as session:
                live = session.scalar(
                    select(func.count()).where(
                        ControlSession.rig_id == RIG, ControlSession.ended_at.is_(None)
                    )
                )
            assert (live or 0) <= 1
            if current_slot():
                ids = {people[n].user_id for n in OUTSIDERS}
                assert snap.controller is None or snap.controller.user_id not in ids
                assert not any(place.user_id in ids for place in snap.queue)

    run_state_machine_as_test(
        Machine,
        settings=settings(
            # Each step is several transactions (a wait: up to 5 heartbeats of 4 people);
            # the ci profile draws the same examples every run. 12 x 10 steps reach every
            # rule in and out of slots; 20 x 12 took 169 s on PostgreSQL on CI.
            max_examples=12,
            stateful_step_count=10,
            deadline=None,
            suppress_health_check=[HealthCheck.too_slow],
        ),
    )
