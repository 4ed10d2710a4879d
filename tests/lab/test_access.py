"""The access model: control, queue, ETA, every way a turn ends, power on demand, cool-down.

Every test runs on SQLite, on a manual clock (nothing sleeps).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import timedelta

import pytest
from sqlalchemy import select

from thermolab.errors import AccessDeniedError, ConflictError, InvalidParameterError, RigError
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import CooldownPolicy, RigConfig
from thermolab.lab.db.models import ControlSession, QueueEntry
from thermolab.lab.service import Lab
from thermolab.rigs import BaseRig, Reading, RigInfo, VirtualClock

from .conftest import PASSWORD, LabFactory

# On SQLite alone: turn and queue rules; their races on both databases are test_fail_closed and
# test_race (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only


def person(lab: Lab, name: str, role: str = "student") -> Principal:
    info = lab.users.add(name, PASSWORD, role)
    return Principal(info.id, info.username, info.role)


def wait(
    lab: Lab,
    clock: ManualClock,
    seconds: float,
    present: Sequence[Principal] = (),
    rig: str = "twin",
) -> None:
    """Let ``seconds`` pass in steps of 10 s; the clients of ``present`` keep polling the rig."""
    left = seconds
    while left > 0:
        step = min(10.0, left)
        clock.advance(step)
        left -= step
        for who in present:
            lab.access.heartbeat(rig, who)
        lab.sweep()


def turns(lab: Lab, rig: str = "twin") -> list[ControlSession]:
    return list(reversed(lab.access.history(rig)))


def test_first_request_controls_and_the_others_queue_in_order(lab: Lab, clock: ManualClock) -> None:
    alice, bob, carol, dave = (person(lab, n) for n in ("alice", "bob", "carol", "dave"))
    view = lab.access.request_control("twin", alice)
    assert view.access.role == "controller"
    assert view.access.time_left == 300.0
    assert view.state == "in_use"

    bob_view = lab.access.request_control("twin", bob)
    carol_view = lab.access.request_control("twin", carol)
    assert (bob_view.access.role, bob_view.access.queue_position) == ("queued", 1)
    assert (carol_view.access.queue_position, carol_view.access.queue_size) == (2, 2)
    assert bob_view.access.estimated_time_until_control == 300.0
    assert carol_view.access.estimated_time_until_control == 600.0
    assert carol_view.access.controller == "alice"

    wait(lab, clock, 100, present=[alice, bob, carol])
    assert lab.access.view("twin", bob).access.estimated_time_until_control == 200.0
    assert lab.access.view("twin", carol).access.estimated_time_until_control == 500.0
    watcher = lab.access.view("twin", dave).access
    assert (watcher.role, watcher.queue_position) == ("watcher", None)
    # A watcher sees how long they would wait if they asked now: behind the two queued.
    assert watcher.estimated_time_until_control == 800.0
    assert lab.access.view("twin", alice).access.time_left == 200.0


def test_asking_again_keeps_the_place(lab: Lab) -> None:
    alice, bob = person(lab, "alice"), person(lab, "bob")
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    again = lab.access.request_control("twin", bob)
    assert again.access.queue_position == 1
    assert lab.access.request_control("twin", alice).access.role == "controller"
    assert again.access.queue_size == 1


def test_release_hands_control_to_the_next_at_once(lab: Lab, clock: ManualClock) -> None:
    alice, bob, carol = (person(lab, n) for n in ("alice", "bob", "carol"))
    for who in (alice, bob, carol):
        lab.access.request_control("twin", who)
    clock.advance(10)
    view = lab.access.release("twin", alice)
    assert view.access.role == "watcher"
    assert view.access.controller == "bob"
    assert lab.access.view("twin", carol).access.queue_position == 1
    first, second = turns(lab)
    assert (first.username, first.end_reason) == ("alice", "released")
    assert first.ended_at == second.started_at == clock.now()
    assert second.ended_at is None


def test_leaving_the_queue(lab: Lab) -> None:
    alice, bob, carol = (person(lab, n) for n in ("alice", "bob", "carol"))
    for who in (alice, bob, carol):
        lab.access.request_control("twin", who)
    assert lab.access.release("twin", bob).access.role == "watcher"
    assert lab.access.view("twin", carol).access.queue_position == 1
    # A mere watcher releasing changes nothing.
    assert lab.access.release("twin", bob).access.controller == "alice"


def test_time_limit_ends_the_turn_at_the_limit(make_lab: LabFactory, clock: ManualClock) -> None:
    lab = make_lab(control_time_limit=60.0)
    alice, bob = person(lab, "alice"), person(lab, "bob")
    start = clock.now()
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    assert lab.access.view("twin", bob).access.estimated_time_until_control == 60.0
    for _ in range(6):  # a command every 10 s: never idle, never gone
        lab.apply_input("twin", alice, 1.0)
        wait(lab, clock, 10, present=[alice, bob])
    first, second = turns(lab)
    assert (first.end_reason, first.ended_at) == ("time_limit", start + timedelta(seconds=60))
    assert (second.username, second.started_at) == ("bob", start + timedelta(seconds=60))


def test_idle_controller_loses_control(lab: Lab, clock: ManualClock) -> None:
    alice = person(lab, "alice")
    start = clock.now()
    lab.access.request_control("twin", alice)
    wait(lab, clock, 50, present=[alice])
    lab.apply_input("twin", alice, 2.0)
    view = lab.access.view("twin", alice)
    assert view.access.idle_time_left == 120.0
    wait(lab, clock, 125, present=[alice])
    (turn,) = turns(lab)
    assert (turn.end_reason, turn.ended_at) == ("idle", start + timedelta(seconds=170))


def test_idle_limit_can_be_off(make_lab: LabFactory, clock: ManualClock) -> None:
    lab = make_lab(idle_limit=None)
    alice = person(lab, "alice")
    lab.access.request_control("twin", alice)
    wait(lab, clock, 150, present=[alice])
    assert lab.access.view("twin", alice).access.role == "controller"


def test_client_gone_ends_the_turn_and_the_queue_moves(lab: Lab, clock: ManualClock) -> None:
    alice, bob = person(lab, "alice"), person(lab, "bob")
    start = clock.now()
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    wait(lab, clock, 20, present=[bob])  # alice's browser is gone
    first, second = turns(lab)
    assert (first.end_reason, first.ended_at) == ("client_gone", start + timedelta(seconds=15))
    assert second.username == "bob"
    assert lab.access.view("twin", bob).access.role == "controller"


def test_a_silent_queued_client_leaves_the_queue(lab: Lab, clock: ManualClock) -> None:
    alice, bob, carol = (person(lab, n) for n in ("alice", "bob", "carol"))
    for who in (alice, bob, carol):
        lab.access.request_control("twin", who)
    wait(lab, clock, 20, present=[alice, carol])
    assert lab.access.view("twin", carol).access.queue_position == 1
    with lab.db.read() as session:
        entry = session.scalars(select(QueueEntry).where(QueueEntry.user_id == bob.user_id)).one()
        assert entry.leave_reason == "client_gone"


def test_any_request_for_the_rig_is_a_heartbeat(lab: Lab, clock: ManualClock) -> None:
    alice = person(lab, "alice")
    lab.access.request_control("twin", alice)
    for _ in range(10):
        clock.advance(10)
        lab.access.view("twin", alice)  # a polling page
        lab.sweep()
    assert lab.access.view("twin", alice).access.role == "controller"
    # The list of all rigs is not about this rig: it does not keep control alive.
    clock.advance(10)
    lab.access.views(alice)
    clock.advance(6)
    lab.sweep()
    assert turns(lab)[0].end_reason == "client_gone"


def test_teacher_kicks_the_controller_or_a_queued_user(lab: Lab) -> None:
    alice, bob, carol = (person(lab, n) for n in ("alice", "bob", "carol"))
    tina = person(lab, "tina", "teacher")
    for who in (alice, bob, carol):
        lab.access.request_control("twin", who)
    with pytest.raises(AccessDeniedError, match="only a teacher"):
        lab.access.kick("twin", bob)
    view = lab.access.kick("twin", tina, "carol")
    assert [slot.username for slot in view.queue or ()] == ["bob"]
    view = lab.access.kick("twin", tina)
    assert view.access.controller == "bob"
    first, _ = turns(lab)
    assert (first.end_reason, first.ended_by) == ("kicked", "tina")
    with pytest.raises(ConflictError, match="neither controls nor waits"):
        lab.access.kick("twin", tina, "alice")


def test_teacher_extends_or_cuts_the_time_limit(lab: Lab, clock: ManualClock) -> None:
    alice, bob = person(lab, "alice"), person(lab, "bob")
    tina = person(lab, "tina", "teacher")
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    with pytest.raises(AccessDeniedError):
        lab.access.extend("twin", alice, 600)
    with pytest.raises(InvalidParameterError, match="finite"):
        lab.access.extend("twin", tina, float("nan"))
    lab.access.extend("twin", tina, 120)
    assert lab.access.view("twin", alice).access.time_left == 420.0
    assert lab.access.view("twin", bob).access.estimated_time_until_control == 420.0
    lab.access.extend("twin", tina, -100)
    assert lab.access.view("twin", alice).access.time_left == 320.0
    view = lab.access.extend("twin", tina, -1000)  # cut to now: the turn ends
    assert view.access.controller == "bob"
    assert turns(lab)[0].end_reason == "time_limit"
    lab.access.release("twin", bob)
    with pytest.raises(ConflictError, match="nobody controls"):
        lab.access.extend("twin", tina, 60)


def test_rig_fault_ends_the_turn_and_blocks_requests_until_cleared(
    lab: Lab, clock: ManualClock
) -> None:
    alice, bob = person(lab, "alice"), person(lab, "bob")
    tina = person(lab, "tina", "teacher")
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    lab.access.report_fault("twin", "output above the limit")
    view = lab.access.view("twin", bob)
    assert (view.state, view.access.controller, view.access.queue_position) == ("fault", None, 1)
    assert view.access.estimated_time_until_control is None
    with pytest.raises(ConflictError, match="has a fault"):
        lab.access.request_control("twin", alice)
    assert turns(lab)[0].end_reason == "rig_fault"
    lab.set_service("twin", tina, True)  # a teacher clears it: the queue moves on
    assert lab.access.view("twin", bob).access.role == "controller"


def test_out_of_service_kicks_everyone_and_refuses_requests(lab: Lab) -> None:
    alice, bob = person(lab, "alice"), person(lab, "bob")
    tina = person(lab, "tina", "teacher")
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    with pytest.raises(AccessDeniedError):
        lab.set_service("twin", alice, False)
    view = lab.set_service("twin", tina, False)
    assert (view.state, view.access.queue_size, view.access.controller) == (
        "out_of_service",
        0,
        None,
    )
    with pytest.raises(ConflictError, match="out of service"):
        lab.access.request_control("twin", alice)
    lab.set_service("twin", tina, True)
    assert lab.access.request_control("twin", alice).access.role == "controller"


def test_server_restart_ends_turns_and_queues_and_powers_rigs_off(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab = make_lab()
    alice, bob = person(lab, "alice"), person(lab, "bob")
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    assert lab.access.snapshot("twin").power.value == "on"
    clock.advance(1)
    restarted = make_lab()
    assert turns(restarted)[0].end_reason == "server_restart"
    snap = restarted.access.snapshot("twin")
    assert (snap.controller, snap.queue, snap.power.value) == (None, (), "off")
    with restarted.db.read() as session:
        entry = session.scalars(select(QueueEntry).where(QueueEntry.user_id == bob.user_id)).one()
        assert entry.leave_reason == "server_restart"


def test_only_the_controller_may_set_the_input_within_the_published_range(lab: Lab) -> None:
    alice, bob = person(lab, "alice"), person(lab, "bob")
    with pytest.raises(AccessDeniedError, match="nobody controls it"):
        lab.apply_input("twin", alice, 1.0)
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    with pytest.raises(AccessDeniedError, match="another user controls it"):
        lab.apply_input("twin", bob, 1.0)
    for bad, message in [
        (10.5, r"u = 10.5 V is outside the input range of rig 'twin': \[-10, 10\] V"),
        (float("nan"), "finite"),
        (float("inf"), "finite"),
        ("5", "must be a number"),
        (True, "must be a number"),
    ]:
        with pytest.raises(InvalidParameterError, match=message):
            lab.apply_input("twin", alice, bad)  # type: ignore[arg-type]
    result = lab.apply_input("twin", alice, -10)
    assert (result.u, result.applied) == (-10.0, None)  # no device attached to this lab
    assert lab.access.view("twin", bob).last_input == -10.0


def test_configured_range_narrows_the_published_one(make_lab: LabFactory) -> None:
    lab = make_lab(input_range=(0.0, 5.0))
    alice = person(lab, "alice")
    lab.access.request_control("twin", alice)
    with pytest.raises(InvalidParameterError, match=r"\[0, 5\] V"):
        lab.apply_input("twin", alice, 6.0)
    assert lab.apply_input("twin", alice, 5.0).u == 5.0


def test_power_on_demand_and_off_after_the_grace_period(lab: Lab, clock: ManualClock) -> None:
    alice = person(lab, "alice")
    assert lab.access.view("twin", alice).state == "off"
    lab.access.request_control("twin", alice)
    clock.advance(10)
    view = lab.access.release("twin", alice)
    assert view.state == "free"
    wait(lab, clock, 55)
    assert lab.access.view("twin", alice).state == "free"
    wait(lab, clock, 5)  # 60 s free with an empty queue
    assert lab.access.view("twin", alice).state == "off"
    assert lab.access.request_control("twin", alice).state == "in_use"


def test_removing_a_user_hands_their_rig_over(lab: Lab) -> None:
    alice, bob = person(lab, "alice"), person(lab, "bob")
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    lab.remove_user("alice")
    assert lab.access.view("twin", bob).access.role == "controller"
    first = turns(lab)[0]
    assert (first.username, first.end_reason, first.user_id) == ("alice", "kicked", None)


def test_every_end_reason_is_recorded(make_lab: LabFactory, clock: ManualClock) -> None:
    lab = make_lab()
    users = [person(lab, f"s{i}") for i in range(6)]
    tina = person(lab, "tina", "teacher")
    s0, s1, s2, s3, s4, s5 = users
    lab.access.request_control("twin", s0)
    lab.access.release("twin", s0)  # released
    lab.access.request_control("twin", s1)
    wait(lab, clock, 20)  # client_gone
    lab.access.request_control("twin", s2)
    wait(lab, clock, 125, present=[s2])  # idle
    lab.access.request_control("twin", s3)
    lab.access.kick("twin", tina)  # kicked
    lab.access.request_control("twin", s4)
    lab.access.extend("twin", tina, -300)  # time_limit
    lab.access.request_control("twin", s5)
    lab.access.report_fault("twin", "sensor unplugged")  # rig_fault
    lab.set_service("twin", tina, True)
    lab.access.request_control("twin", s0)
    make_lab()  # server_restart
    reasons = [turn.end_reason for turn in turns(lab)]
    assert reasons == [
        "released",
        "client_gone",
        "idle",
        "kicked",
        "time_limit",
        "rig_fault",
        "server_restart",
    ]


class _Box(BaseRig):
    """A rig whose output the test sets, recording every input applied."""

    def __init__(self) -> None:
        super().__init__(RigInfo("box", "twin", -10.0, 10.0, "V", "V", 0.0, None), VirtualClock())
        self.output = 0.0
        self.applied: list[float] = []

    def _apply_input(self, u: float) -> float:
        self.applied.append(u)
        return u

    def _read_output(self) -> Reading:
        return Reading(self.output, self.clock.now())

    def _make_safe(self) -> None:
        self.applied.append(0.0)

    def _release(self) -> None:
        pass


def test_cool_down_holds_the_next_controller_until_near_ambient(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    box = _Box()

    def opener(rig: RigConfig) -> BaseRig:
        return box if rig.id == "twin" else _Box()

    cooldown = CooldownPolicy(mode="ambient", tolerance=0.1, max_seconds=600, input=-10.0)
    lab = make_lab(opener=opener, cooldown=cooldown)
    alice, bob = person(lab, "alice"), person(lab, "bob")
    lab.access.request_control("twin", alice)
    lab.sweep()  # first reading of the cold rig: its ambient
    assert lab.access.snapshot("twin").ambient_output == 0.0
    assert lab.apply_input("twin", alice, 8.0).applied == 8.0
    box.output = 5.0
    lab.access.request_control("twin", bob)
    view = lab.access.release("twin", alice)
    assert view.state == "cooldown"
    assert box.applied[-1] == -10.0  # the fan runs during the cool-down
    bob_view = lab.access.view("twin", bob)
    assert (bob_view.access.role, bob_view.access.queue_position) == ("queued", 1)
    assert bob_view.access.estimated_time_until_control == 600.0
    wait(lab, clock, 30, present=[bob])
    assert lab.access.view("twin", bob).access.role == "queued"
    box.output = 0.05
    wait(lab, clock, 5, present=[bob])
    view = lab.access.view("twin", bob)
    assert (view.access.role, view.state) == ("controller", "in_use")
    assert box.applied[-1] == 0.0  # the new controller starts from the safe input


def test_cool_down_gives_up_after_its_maximum(make_lab: LabFactory, clock: ManualClock) -> None:
    cooldown = CooldownPolicy(mode="ambient", tolerance=0.1, max_seconds=100, ambient=0.0)
    box = _Box()
    box.output = 3.0  # and it never cools: the cool-down ends at its maximum
    lab = make_lab(opener=lambda rig: box, cooldown=cooldown)
    alice, bob = person(lab, "alice"), person(lab, "bob")
    lab.access.request_control("twin", alice)
    lab.access.request_control("twin", bob)
    started = clock.now()
    lab.access.release("twin", alice)
    wait(lab, clock, 95, present=[bob])
    assert lab.access.view("twin", bob).access.role == "queued"
    wait(lab, clock, 5, present=[bob])
    control = lab.access.snapshot("twin").controller
    assert control is not None
    assert control.username == "bob"
    assert control.started_at == started + timedelta(seconds=100)


def test_live_rig_receives_inputs_and_goes_safe_on_handover(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    boxes: dict[str, _Box] = {}

    def opener(rig: RigConfig) -> BaseRig:
        boxes[rig.id] = _Box()
        return boxes[rig.id]

    lab = make_lab(opener=opener)
    alice, bob = person(lab, "alice"), person(lab, "bob")
    box = boxes["twin"]
    assert not box.powered
    lab.access.request_control("twin", alice)
    assert box.powered
    assert lab.apply_input("twin", alice, 3.0).applied == 3.0
    assert lab.access.view("twin", alice).published.live
    lab.access.request_control("twin", bob)
    lab.access.release("twin", alice)
    assert box.applied[-1] == 0.0
    lab.access.release("twin", bob)
    wait(lab, clock, 60)
    assert not box.powered


def test_a_rig_that_failed_to_open_is_opened_again_when_the_fault_is_cleared(
    make_lab: LabFactory,
) -> None:
    failures = ["no such port"]

    def opener(rig: RigConfig) -> BaseRig:
        if rig.id == "twin" and failures:
            raise RigError(failures.pop())
        return _Box()

    lab = make_lab(opener=opener)
    ana, tina = person(lab, "ana"), person(lab, "tina", "teacher")
    view = lab.access.view("twin", ana)
    assert view.state == "fault"
    assert "no such port" in (view.fault or "")
    assert not view.published.live
    lab.set_service("twin", tina, True)
    view = lab.access.request_control("twin", ana)
    assert (view.state, view.published.live) == ("in_use", True)


def test_the_hub_follows_the_device_when_something_else_powered_it_off(
    make_lab: LabFactory,
) -> None:
    box = _Box()
    lab = make_lab(opener=lambda rig: box if rig.id == "twin" else _Box())
    ana = person(lab, "ana")
    lab.access.request_control("twin", ana)
    lab.apply_input("twin", ana, 4.0)
    box.power_off()  # what the runner does at the end of a run
    lab.access.heartbeat("twin", ana)  # every write on the rig reconciles the device
    assert box.powered
    assert box.applied[-1] == 0.0  # powered again, from the safe input
    assert lab.apply_input("twin", ana, 5.0).applied == 5.0
