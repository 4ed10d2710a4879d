"""The turn rules as a pure transition table (no database, no clock)."""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC, datetime, timedelta

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.lab.access.rules import (
    Slot,
    Turn,
    TurnRules,
    TurnState,
    Waiting,
    end_turn,
    is_due,
    next_state,
    queue_wait,
)
from thermolab.lab.config import CooldownPolicy
from thermolab.lab.db.models import PowerState, TurnEndReason

T0 = datetime(2026, 1, 1, tzinfo=UTC)
COOLING = CooldownPolicy(mode="ambient", tolerance=0.5, max_seconds=600.0, ambient=20.0)


def rules(cooldown: CooldownPolicy | None = None, idle: float | None = 120.0) -> TurnRules:
    return TurnRules(timedelta(seconds=15), 300.0, idle, 60.0, cooldown or CooldownPolicy())


def at(seconds: float) -> datetime:
    return T0 + timedelta(seconds=seconds)


def free(**changes: object) -> TurnState:
    state = TurnState(
        in_service=True,
        faulted=False,
        power=PowerState.ON,
        needs_cooldown=False,
        cooling_since=None,
        vacant_since=None,
        ambient_output=20.0,
        turn=None,
        queue=(),
        run_active=False,
    )
    return replace(state, **changes)  # type: ignore[arg-type]


def turn(user: int = 1, *, seen: float = 0.0, active: float = 0.0) -> Turn:
    return Turn(user, T0, at(300), at(seen), at(active))


def test_the_head_of_the_queue_gets_a_free_rig_at_once() -> None:
    after = next_state(free(queue=(Waiting(7, T0), Waiting(8, T0))), rules(), T0, None)
    assert after.turn == Turn(7, T0, at(300), T0, T0)
    assert after.queue == (Waiting(8, T0),)
    assert after.vacant_since is None


@pytest.mark.parametrize(
    ("state", "now", "reason", "ended_at"),
    [
        (free(turn=turn(seen=290, active=290)), at(300), TurnEndReason.TIME_LIMIT, at(300)),
        (free(turn=turn(seen=0, active=0)), at(20), TurnEndReason.CLIENT_GONE, at(15)),
        (free(turn=turn(seen=200, active=0)), at(200), TurnEndReason.IDLE, at(120)),
    ],
)
def test_a_turn_ends_at_the_first_limit_reached_dated_when_it_was(
    state: TurnState, now: datetime, reason: TurnEndReason, ended_at: datetime
) -> None:
    assert is_due(state, rules(), now, None)
    after = next_state(state, rules(), now, None)
    assert after.turn is None
    assert after.ended is not None
    assert (after.ended.reason, after.ended.at) == (reason, ended_at)


def test_the_idle_limit_does_not_run_while_a_run_samples() -> None:
    sampling = free(turn=turn(seen=200, active=0), run_active=True)
    assert not is_due(sampling, rules(), at(200), None)


def test_a_running_run_covers_the_turn_until_it_ends() -> None:
    # Past the time limit, the client in touch: the run goes on, the turn with it.
    sampling = free(
        turn=turn(seen=1990, active=1990), run_active=True, queue=(Waiting(7, at(1990)),)
    )
    assert not is_due(sampling, rules(), at(2000), None)
    # The client gone still ends it (the run is then ENDed, its data kept).
    gone = next_state(sampling, rules(), at(2010), None)
    assert gone.ended is not None
    assert gone.ended.reason is TurnEndReason.CLIENT_GONE
    # The run over, the time limit applies at once, dated when it was reached.
    after = next_state(replace(sampling, run_active=False), rules(), at(2000), None)
    assert after.ended is not None
    assert (after.ended.reason, after.ended.at) == (TurnEndReason.TIME_LIMIT, at(300))
    assert after.turn is not None
    assert after.turn.user_id == 7


def test_the_queues_wait_counts_the_run_going() -> None:
    r = rules()
    assert queue_wait(100.0, None, 0.0, 1, r) == 100.0
    assert queue_wait(100.0, 1700.0, 0.0, 1, r) == 1700.0  # the run outlasts the turn
    assert queue_wait(100.0, 50.0, 0.0, 3, r) == 100.0 + 2 * 300.0
    assert queue_wait(None, None, 42.0, 2, r) == 42.0 + 300.0  # cooling, nobody controls
    cooling = rules(COOLING)
    assert queue_wait(100.0, 1700.0, 0.0, 2, cooling) == 1700.0 + 600.0 + (300.0 + 600.0)


def test_silent_queue_places_are_dropped_when_their_client_timed_out() -> None:
    state = free(turn=turn(seen=100, active=100), queue=(Waiting(7, at(0)), Waiting(8, at(95))))
    after = next_state(state, rules(), at(100), None)
    assert after.queue == (Waiting(8, at(95)),)
    assert after.left == ((Waiting(7, at(0)), at(15)),)


def test_a_rig_with_a_cooldown_cools_between_turns_then_hands_over() -> None:
    r = rules(COOLING)
    ended = end_turn(
        free(turn=turn(), queue=(Waiting(7, at(9)),)), TurnEndReason.RELEASED, at(10), r, at(10)
    )
    assert (ended.power, ended.needs_cooldown, ended.cooling_since) == (
        PowerState.COOLING,
        True,
        at(10),
    )
    waiting = next_state(ended, r, at(10), (25.0, at(10)))
    assert waiting.turn is None  # still warm
    assert not is_due(replace(waiting, queue=(Waiting(7, at(19)),)), r, at(20), (25.0, at(19)))
    cooled = next_state(replace(waiting, queue=(Waiting(7, at(29)),)), r, at(30), (20.2, at(29)))
    assert cooled.power is PowerState.ON
    assert cooled.turn is not None
    assert cooled.turn.user_id == 7


def test_a_vacant_rig_powers_off_after_its_grace() -> None:
    vacant = next_state(free(), rules(), T0, None)
    assert vacant.vacant_since == T0
    assert not is_due(vacant, rules(), at(59), None)
    assert next_state(vacant, rules(), at(60), None).power is PowerState.OFF


@pytest.mark.parametrize("changes", [{"in_service": False}, {"faulted": True}])
def test_out_of_service_or_faulted_rigs_are_off_and_hand_nothing_over(
    changes: dict[str, object],
) -> None:
    state = free(queue=(Waiting(7, T0),), **changes)
    after = next_state(state, rules(), T0, None)
    assert (after.power, after.turn, after.queue) == (PowerState.OFF, None, state.queue)
    assert not is_due(after, rules(), T0, None)


def test_the_first_reading_of_a_cold_powered_rig_is_its_ambient() -> None:
    cold = free(ambient_output=None, vacant_since=T0)
    assert not is_due(cold, rules(), T0, None)
    assert is_due(cold, rules(), T0, (21.5, T0))
    assert next_state(cold, rules(), T0, (21.5, T0)).ambient_output == 21.5


# -- booked slots (issue #10, item 5) -------------------------------------------------------


def slot(start: float, end: float, members: frozenset[int] = frozenset({7})) -> Slot:
    return Slot(1, 1, at(start), at(end), members)


def test_at_a_slots_start_an_outsider_loses_the_turn_even_mid_run() -> None:
    # User 1 controls with a run going; 8 (outsider) and 7 (of the course) wait.
    state = free(
        turn=turn(seen=100, active=100),
        run_active=True,
        queue=(Waiting(8, at(100)), Waiting(7, at(100))),
        slots=(slot(100, 200),),
    )
    assert not is_due(replace(state, slots=(slot(101, 200),)), rules(), at(100), None)
    assert is_due(state, rules(), at(100), None)  # what is due next, from the same table
    after = next_state(state, rules(), at(100), None)
    assert after.ended is not None
    assert (after.ended.reason, after.ended.at) == (TurnEndReason.BOOKED, at(100))
    assert after.booked_out == ((Waiting(8, at(100)), at(100)),)
    assert after.turn is not None
    assert after.turn.user_id == 7  # the course's student, queued behind, gets the rig
    assert after.queue == ()


def test_inside_a_slot_the_course_queues_as_usual_and_after_it_everyone_does() -> None:
    state = free(turn=turn(7, seen=150, active=150), queue=(Waiting(9, at(150)),))
    inside = replace(state, slots=(slot(100, 200, frozenset({7, 9})),))
    assert not is_due(inside, rules(), at(150), None)
    # After the slot (or with no slot) an outsider waits and is not dropped.
    outsider = replace(state, queue=(Waiting(8, at(250)),), turn=turn(7, seen=250, active=250))
    assert not is_due(replace(outsider, slots=(slot(100, 200),)), rules(), at(250), None)


@settings(max_examples=300, deadline=None)
@given(
    controller=st.one_of(st.none(), st.integers(1, 6)),
    waiting=st.lists(st.integers(1, 6), unique=True, max_size=5),
    members=st.frozensets(st.integers(1, 6)),
    start=st.integers(0, 400),
    length=st.integers(1, 400),
    now=st.integers(0, 800),
    run_active=st.booleans(),
)
def test_no_outsider_holds_or_waits_for_a_rig_during_a_slot(
    controller: int | None,
    waiting: list[int],
    members: frozenset[int],
    start: int,
    length: int,
    now: int,
    run_active: bool,
) -> None:
    queue = tuple(Waiting(u, at(now)) for u in waiting if u != controller)
    state = free(
        turn=None if controller is None else turn(controller, seen=now, active=now),
        queue=queue,
        run_active=run_active and controller is not None,
        slots=(Slot(1, 1, at(start), at(start + length), members),),
    )
    after = next_state(state, rules(), at(now), None)
    during = start <= now < start + length
    people = [w.user_id for w in after.queue] + ([after.turn.user_id] if after.turn else [])
    assert len(people) == len(set(people))  # one turn each, nobody twice
    if during:
        assert all(p in members for p in people), "an outsider at the rig during its slot"
        # And the table is settled: nothing more is due at the same instant.
        assert not is_due(after, rules(), at(now), None)
    else:
        # Outside the slot the rules are those of a rig without bookings.
        plain = next_state(replace(state, slots=()), rules(), at(now), None)
        assert (after.turn, after.queue, after.ended) == (plain.turn, plain.queue, plain.ended)
