"""The run's state machine: legal paths, illegal transitions, end reasons."""

from __future__ import annotations

import itertools

import pytest

from thermolab.errors import RunStateError
from thermolab.runner import EndReason, RunState, RunStateMachine

LEGAL = {
    (RunState.IDLE, RunState.RUNNING),
    (RunState.IDLE, RunState.ABORTED),
    (RunState.RUNNING, RunState.ENDING),
    (RunState.RUNNING, RunState.FAULTED),
    (RunState.RUNNING, RunState.ABORTED),
    (RunState.ENDING, RunState.FINISHED),
    (RunState.ENDING, RunState.FAULTED),
    (RunState.ENDING, RunState.ABORTED),
}

# The shortest legal path from IDLE to each state.
PATH = {
    RunState.IDLE: [],
    RunState.RUNNING: [RunState.RUNNING],
    RunState.ENDING: [RunState.RUNNING, RunState.ENDING],
    RunState.FINISHED: [RunState.RUNNING, RunState.ENDING, RunState.FINISHED],
    RunState.FAULTED: [RunState.RUNNING, RunState.FAULTED],
    RunState.ABORTED: [RunState.ABORTED],
}


@pytest.mark.parametrize(("src", "dst"), list(itertools.product(RunState, RunState)))
def test_exactly_the_documented_transitions_are_allowed(src: RunState, dst: RunState) -> None:
    machine = RunStateMachine("test")
    for step in PATH[src]:
        machine.transition(step)
    assert machine.state is src
    assert machine.can(dst) == ((src, dst) in LEGAL)
    if (src, dst) in LEGAL:
        assert machine.transition(dst) is src
        assert machine.state is dst
    else:
        with pytest.raises(RunStateError, match=f"test: illegal transition {src.value}"):
            machine.transition(dst)
        assert machine.state is src


def test_terminal_states_allow_nothing() -> None:
    assert {s for s in RunState if s.terminal} == {
        RunState.FINISHED,
        RunState.FAULTED,
        RunState.ABORTED,
    }
    machine = RunStateMachine()
    machine.transition(RunState.ABORTED)
    with pytest.raises(RunStateError, match="none, the run is over"):
        machine.transition(RunState.RUNNING)


@pytest.mark.parametrize(
    ("reason", "state"),
    [
        (EndReason.COMPLETED, RunState.FINISHED),
        (EndReason.ENDED, RunState.FINISHED),
        (EndReason.INTERLOCK, RunState.FAULTED),
        (EndReason.RIG_FAULT, RunState.FAULTED),
        (EndReason.WATCHDOG, RunState.FAULTED),
        (EndReason.ERROR, RunState.FAULTED),
        (EndReason.ABORTED, RunState.ABORTED),
    ],
)
def test_each_end_reason_has_its_terminal_state(reason: EndReason, state: RunState) -> None:
    assert reason.final_state is state
