"""Fail closed: a run exists only inside a live turn, whatever order requests race in.

Each example is a sequence of steps. A racing step sends the controller's
START at the same instant (threads behind a barrier) as something else:
an input, the controller's release, a teacher's kick, taking the rig out of
service, the turn's time limit running out (the clock moved, then the
sweep), or a slot booked for a course the controller is not in beginning
(booked, the clock moved to its start, then the sweep). A restart step
closes the lab and opens a new one on the database.
After every step the invariant is checked: at most one controller, no run
outside a turn, the device left to the hub (safe) when no run goes. The rig's
clock is a :class:`StepClock`: time passes only as far as the test allows.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sqlalchemy import func, select

from thermolab.errors import (
    AccessDeniedError,
    ConflictError,
    NotFoundError,
    PreviousRunEndingError,
    TurnEndedError,
)
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import RigConfig
from thermolab.lab.db.models import ControlSession, Course, CourseMember, Run, RunStatus
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig

from .conftest import PASSWORD, LabFactory
from .test_runs import StepClock, lab_request, until

RIG = "twin"
RACERS = ("input", "release", "kick", "out_of_service", "expiry", "slot")
_EPOCH = datetime(2025, 12, 1, tzinfo=UTC)  # before the manual clock's start
STEPS = st.lists(st.sampled_from((*RACERS, "restart")), min_size=1, max_size=3)


class Scene:
    """A lab on the test database, its users, and the rig clock the runs sleep on."""

    def __init__(self, make_lab: LabFactory, clock: ManualClock) -> None:
        self.make_lab = make_lab
        self.clock = clock
        self.rig_clock = StepClock()
        self.lab = self._open()
        self.ana = self._person("ana", "student")
        self.tina = self._person("tina", "teacher")
        # A course ana is not in, whose slots take the rig from her.
        with contextlib.suppress(ConflictError):
            self.lab.courses.create("others", "Another class", "tina")

    def _open(self) -> Lab:
        rig_clock = self.rig_clock

        def opener(rig: RigConfig) -> Rig:
            return TwinRig("paper" if rig.id == RIG else "tclab", clock=rig_clock)

        return self.make_lab(opener=opener, control_time_limit=60.0, max_run_seconds=1e6)

    def _person(self, name: str, role: str) -> Principal:
        try:  # the database outlives one Hypothesis example
            info = self.lab.users.get(name)
        except NotFoundError:
            info = self.lab.users.add(name, PASSWORD, role)
        return Principal(info.id, info.username, info.role)

    def restart(self) -> None:
        self.rig_clock.allow(math.inf)
        self.lab.close()
        self.rig_clock = StepClock()
        self.lab = self._open()

    def ready(self) -> None:
        """Ana controls the rig in service, with no run going (and no slot booked)."""
        lab = self.lab
        for booking in lab.bookings.calendar(self.tina, _EPOCH, _EPOCH + timedelta(days=60)):
            lab.bookings.cancel(self.tina, booking.id)
        if lab.runs.running(RIG) is not None:
            lab.runs.stop(RIG, self.tina)
            self.rig_clock.allow(self.rig_clock.now() + 5.0)
            lab.runs.wait(RIG, timeout=30)
        lab.set_service(RIG, self.tina, True)
        lab.access.request_control(RIG, self.ana)
        assert lab.access.snapshot(RIG).controller is not None

    def settle(self) -> None:
        """Let ended runs take their last sample and be stored."""
        self.rig_clock.allow(self.rig_clock.now() + 5.0)
        running = self.lab.runs.running(RIG)
        if running is None:
            return
        with self.lab.db.read() as session:
            turn = session.scalar(select(Run.control_session_id).where(Run.id == running))
        controller = self.lab.access.snapshot(RIG).controller
        if controller is None or controller.id != turn:  # its turn is over: it must end
            self.lab.runs.wait(RIG, timeout=30)

    def race(self, other: str) -> dict[str, BaseException | None]:
        lab = self.lab
        actions: dict[str, Callable[[], Any]] = {
            "start": lambda: lab.runs.start(RIG, self.ana, lab_request(samples=100_000)),
            "input": lambda: lab.apply_input(RIG, self.ana, 3.0),
            "release": lambda: lab.access.release(RIG, self.ana),
            "kick": lambda: lab.access.kick(RIG, self.tina),
            "out_of_service": lambda: lab.set_service(RIG, self.tina, False),
            "expiry": self._expire,
            "slot": self._slot,
        }
        barrier = threading.Barrier(2)
        outcome: dict[str, BaseException | None] = {}

        def run(name: str) -> None:
            barrier.wait()
            try:
                actions[name]()
                outcome[name] = None
            except Exception as exc:  # judged below
                outcome[name] = exc

        threads = [threading.Thread(target=run, args=(name,)) for name in ("start", other)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(60)
        return outcome

    def _expire(self) -> None:
        self.clock.advance(61.0)
        self.lab.sweep()

    def _slot(self) -> None:
        now = self.clock.now()
        second = timedelta(seconds=1)
        self.lab.bookings.create(self.tina, "others", [RIG], now + second, now + 3600 * second)
        self.clock.advance(1.0)
        self.lab.sweep()

    def check(self) -> None:
        """The invariant: one controller at most; a run only inside the live turn."""
        lab = self.lab
        with lab.db.read() as session:
            controls = list(
                session.scalars(
                    select(ControlSession.id).where(
                        ControlSession.rig_id == RIG, ControlSession.ended_at.is_(None)
                    )
                )
            )
            running = list(
                session.scalars(
                    select(Run).where(Run.rig_id == RIG, Run.status == RunStatus.RUNNING.value)
                )
            )
        assert len(controls) <= 1
        assert len(running) <= 1
        # No outsider in control during a slot: the controller, if any, is in its course.
        now = self.clock.now()
        slots = lab.bookings.calendar(self.tina, now, now + timedelta(microseconds=1), RIG)
        if slots and controls:
            with lab.db.read() as session:
                holder = session.scalar(
                    select(ControlSession.user_id).where(ControlSession.id == controls[0])
                )
                course = session.scalar(select(Course.id).where(Course.name == slots[0].course))
                member = session.scalar(
                    select(CourseMember.id).where(
                        CourseMember.course_id == course, CourseMember.user_id == holder
                    )
                )
            assert member is not None, "an outsider in control during a slot"
        live = lab.runs.running(RIG)
        if running:
            assert controls == [running[0].control_session_id], "a run outside its turn"
            assert live == running[0].id
        else:
            assert live is None
        if not controls:
            # No turn: no run, and the hub holds the rig at its safe input or off.
            assert not lab.hub.powered(RIG) or lab.hub.applied(RIG) in (
                None,
                lab.hub.published(RIG).safe_input,
            )


@pytest.mark.slow
@settings(
    max_examples=4,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(steps=STEPS)
def test_a_run_never_outlives_its_turn(
    make_lab: LabFactory, clock: ManualClock, steps: list[str]
) -> None:
    scene = Scene(make_lab, clock)
    try:
        for step in steps:
            scene.ready()
            if step == "restart":
                scene.lab.runs.start(RIG, scene.ana, lab_request(samples=100_000))
                scene.restart()
                scene.check()
                assert scene.lab.access.snapshot(RIG).controller is None
                continue
            outcome = scene.race(step)
            # The turn-ending request always succeeds; START may lose: 409 turn_ended when
            # it arrived during the turn, 403 when the turn had ended before it arrived.
            assert outcome[step] is None, outcome[step]
            start = outcome["start"]
            assert start is None or isinstance(start, TurnEndedError | AccessDeniedError), start
            scene.lab.sweep()
            scene.settle()
            scene.check()
    finally:
        scene.rig_clock.allow(math.inf)
        scene.lab.runs.wait(RIG, timeout=30)


def test_the_next_controller_starts_right_after_a_hand_over(make_lab: LabFactory) -> None:
    rig_clock = StepClock()

    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=rig_clock)

    lab = make_lab(opener=opener)
    ana = Principal(*_add(lab, "ana"))
    ben = Principal(*_add(lab, "ben"))
    lab.access.request_control(RIG, ana)
    lab.access.request_control(RIG, ben)
    lab.runs.start(RIG, ana, lab_request(samples=1000))
    lab.access.release(RIG, ana)  # ben controls now; ana's run is still taking its sample
    threading.Timer(0.2, lambda: rig_clock.allow(5.0)).start()
    run = lab.runs.start(RIG, ben, lab_request(samples=1000))  # no spurious 409
    assert run.status == "running"
    rig_clock.allow(math.inf)
    lab.runs.stop(RIG, ben)
    lab.runs.wait(RIG, timeout=30)
    with lab.db.read() as session:
        ended = session.scalar(select(func.count()).where(Run.status != RunStatus.RUNNING.value))
    assert ended == 2


class Pause:
    """A checkpoint of START that holds it at one point until the test lets it go on."""

    def __init__(self, at: str) -> None:
        self.at = at
        self.reached = threading.Event()
        self.resume = threading.Event()

    def __call__(self, name: str) -> None:
        if name == self.at:
            self.reached.set()
            assert self.resume.wait(30), "the test never let START go on"


def _turn_over(lab: Lab) -> bool:
    with lab.db.read() as session:
        live = session.scalar(
            select(func.count()).where(
                ControlSession.rig_id == RIG, ControlSession.ended_at.is_(None)
            )
        )
    return live == 0


def _forced(scene: Scene, pause_at: str, racer: str) -> dict[str, BaseException | None]:
    """START held at ``pause_at`` while ``racer`` ends the turn, then let go on."""
    lab = scene.lab
    pause = Pause(pause_at)
    lab.runs.checkpoint = pause
    outcome: dict[str, BaseException | None] = {}
    actions: dict[str, Callable[[], Any]] = {
        "start": lambda: lab.runs.start(RIG, scene.ana, lab_request(samples=100_000)),
        "release": lambda: lab.access.release(RIG, scene.ana),
        "kick": lambda: lab.access.kick(RIG, scene.tina),
        "out_of_service": lambda: lab.set_service(RIG, scene.tina, False),
        "expiry": scene._expire,
        "slot": scene._slot,
    }

    def run(name: str) -> None:
        try:
            actions[name]()
            outcome[name] = None
        except Exception as exc:  # judged by the caller
            outcome[name] = exc

    starting = threading.Thread(target=run, args=("start",))
    starting.start()
    assert pause.reached.wait(30)
    ending = threading.Thread(target=run, args=(racer,))
    ending.start()
    if (pause_at, racer) == ("start:committed", "out_of_service"):
        # Taking a rig out of service clears its fault under the hub lock before it
        # commits: it cannot come between START's commit and its run, it waits.
        until(lambda: ending.is_alive(), timeout=30)
    elif pause_at == "start:committed" and racer in ("expiry", "slot"):
        # The committed run covers the turn: the time limit ends nothing (the sweep may
        # wait for the hub lock START holds to take its readings; it goes on after).
        ending.join(1.0)
    else:
        # The turn's end is committed while START is held (the racer may then wait for
        # the rig's hub lock, which a START past its transaction holds).
        until(lambda: _turn_over(lab), timeout=30)
    pause.resume.set()
    for thread in (starting, ending):
        thread.join(60)
    lab.runs.checkpoint = lambda name: None
    return outcome


# Where the forced order cannot make START lose, and why.
START_WINS = {
    ("start:committed", "out_of_service"): "waits for the hub lock START holds, then ENDs the run",
    ("start:committed", "expiry"): "a committed run covers its turn: the time limit waits",
    ("start:committed", "slot"): "the sweep waits for the hub lock START holds, then the slot "
    "ends the turn and its run",
}


@pytest.mark.parametrize("racer", ["release", "kick", "out_of_service", "expiry", "slot"])
@pytest.mark.parametrize("pause_at", ["start:arrived", "start:committed"])
def test_a_start_that_loses_the_race_gets_turn_ended_every_time(
    make_lab: LabFactory, clock: ManualClock, pause_at: str, racer: str
) -> None:
    # The race forced, not hoped for: the turn ends before START's transaction
    # (start:arrived) or between its commit and the run's first sample (start:committed).
    scene = Scene(make_lab, clock)
    try:
        scene.ready()
        outcome = _forced(scene, pause_at, racer)
        assert outcome[racer] is None, outcome[racer]
        lost = outcome["start"]
        if (pause_at, racer) in START_WINS:
            assert lost is None, lost
        else:
            assert isinstance(lost, TurnEndedError), lost  # 409 turn_ended, not 403
            assert "ended" in str(lost)
        scene.lab.sweep()
        scene.settle()
        scene.check()
        assert scene.lab.runs.running(RIG) is None
    finally:
        scene.rig_clock.allow(math.inf)
        scene.lab.runs.wait(RIG, timeout=30)


def test_a_runs_late_sample_does_not_become_the_idle_rigs_input(make_lab: LabFactory) -> None:
    # A run's recorder hands samples in by batches, the last perhaps after the run let
    # the rig go: their input is history, and the hub keeps saying what the rig has.
    lab = make_lab()
    hub = lab.hub
    hub.claim(RIG)
    hub.note_sample(RIG, 6.0, 30.0, of_run=True)
    assert hub.applied(RIG) == 6.0  # during the run: the run's input
    hub.release(RIG)
    before = hub.applied(RIG)
    hub.note_sample(RIG, 7.0, 31.0, of_run=True)  # the recorder's last batch, late
    assert hub.applied(RIG) == before
    hub.note_sample(RIG, 0.5, 25.0)  # a rig host's idle reading still counts
    assert hub.applied(RIG) == 0.5


def test_a_rig_its_run_powered_off_is_said_off_as_soon_as_the_run_lets_it_go(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    # Between the run's release of the rig and the hub's next reconcile, the hub said
    # "powered, at the run's last input" of a rig the run had switched off (CI saw it in
    # test_a_start_that_loses_the_race_gets_turn_ended_every_time: 6.0 with no turn).
    scene = Scene(make_lab, clock)
    scene.ready()  # a controller: the rig is open and powered
    hub = scene.lab.hub
    driver = hub.driver(RIG)
    assert driver is not None
    assert hub.powered(RIG)
    hub.claim(RIG)
    hub.note_sample(RIG, 6.0, 30.0, of_run=True)
    driver.power_off()  # what a run does as it ends
    hub.release(RIG)
    assert not hub.powered(RIG)
    assert hub.applied(RIG) is None


def test_a_start_after_the_turn_ended_is_refused_not_a_lost_race(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    scene = Scene(make_lab, clock)
    scene.ready()
    scene.lab.access.release(RIG, scene.ana)
    with pytest.raises(AccessDeniedError):  # 403: she had no turn when it arrived
        scene.lab.runs.start(RIG, scene.ana, lab_request())


def test_the_next_controllers_start_waits_for_the_previous_run_or_says_why(
    make_lab: LabFactory,
) -> None:
    rig_clock = StepClock()

    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=rig_clock)

    lab = make_lab(opener=opener)
    try:
        _hand_over_while_the_run_ends(lab, rig_clock)
    finally:
        rig_clock.allow(math.inf)


def _hand_over_while_the_run_ends(lab: Lab, rig_clock: StepClock) -> None:
    ana = Principal(*_add(lab, "ana"))
    ben = Principal(*_add(lab, "ben"))
    lab.access.request_control(RIG, ana)
    lab.access.request_control(RIG, ben)
    first = lab.runs.start(RIG, ana, lab_request(samples=1000))
    # Her first sample (t = 0) taken: an END before it would end the run without the
    # clock moving, and there would be nothing left for ben's START to wait for.
    active = lab.runs._going(RIG)
    assert active is not None
    until(lambda: active.experiment.k >= 1)
    lab.access.release(RIG, ana)  # ben controls; ana's run cannot take its last sample yet
    lab.runs.handover_wait = 0.2
    with pytest.raises(PreviousRunEndingError) as still_ending:  # 409 previous_run_ending
        lab.runs.start(RIG, ben, lab_request(samples=1000))
    assert f"run {first.id}" in str(still_ending.value)
    with pytest.raises(AccessDeniedError):  # ana's turn is over: 403, not a 409
        lab.runs.start(RIG, ana, lab_request(samples=1000))
    rig_clock.allow(5.0)  # the previous run stores its end...
    lab.runs.handover_wait = 30.0  # (however slow a loaded machine is at storing it)
    run = lab.runs.start(RIG, ben, lab_request(samples=1000))  # ...and ben's START waits for it
    assert run.status == "running"
    assert run.id != first.id
    rig_clock.allow(math.inf)
    lab.runs.stop(RIG, ben)
    lab.runs.wait(RIG, timeout=30)


def _add(lab: Lab, name: str) -> tuple[int, str, Any]:
    info = lab.users.add(name, PASSWORD, "student")
    return info.id, info.username, info.role


@pytest.mark.parametrize("run_id", ["2147483648", "99999999999999999999999", "0", "-1"])
@pytest.mark.parametrize("suffix", ["", "/samples.csv", "/export.json"])
def test_a_run_id_out_of_range_is_refused_not_a_500(
    app_client: Callable[..., Any], lab: Lab, run_id: str, suffix: str
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    client = app_client("ana")
    response = client.get(f"/api/runs/{run_id}{suffix}")
    assert response.status_code == 422, response.text
    assert response.json()["code"] == "invalid_request"
    assert client.get(f"/api/runs/2147483647{suffix}").status_code == 404
