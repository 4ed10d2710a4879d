"""The lifecycle of one experiment run: an explicit state machine.

A run goes through the paper's START / END semantics::

    IDLE --start--> RUNNING --(samples taken | END)--> ENDING --> FINISHED
    IDLE --abort--> ABORTED
    RUNNING/ENDING --(rig fault, interlock, watchdog, error)--> FAULTED
    RUNNING/ENDING --(abort, SIGINT, SIGTERM)--> ABORTED

FINISHED, FAULTED and ABORTED are terminal. Any other transition is a
programming error and raises :class:`~thermolab.errors.RunStateError`.
The actuator is driven only in RUNNING; the runner puts it at the rig's safe
value before it leaves RUNNING, whatever the way out.
"""

from __future__ import annotations

import enum
import threading

from thermolab.errors import RunStateError

__all__ = ["EndReason", "RunState", "RunStateMachine"]


class RunState(enum.Enum):
    """State of an experiment run.

    Attributes
    ----------
    IDLE
        Created, not started: nothing is applied to the rig.
    RUNNING
        Sampling: the schedule is running and the input is applied.
    ENDING
        Sampling has stopped and the actuator is safe; identifiers are
        computing their final estimates (SRM appears here) and records are
        being closed.
    FINISHED
        Ended normally: all requested samples taken, or END requested.
    FAULTED
        Stopped by a rig fault, an interlock, the watchdog or an exception.
    ABORTED
        Stopped by :meth:`~thermolab.runner.Experiment.abort`, SIGINT or SIGTERM.
    """

    IDLE = "idle"
    RUNNING = "running"
    ENDING = "ending"
    FINISHED = "finished"
    FAULTED = "faulted"
    ABORTED = "aborted"

    @property
    def terminal(self) -> bool:
        """``True`` for FINISHED, FAULTED and ABORTED.

        Examples
        --------
        >>> RunState.FAULTED.terminal, RunState.ENDING.terminal
        (True, False)
        """
        return self in _TERMINAL


class EndReason(enum.Enum):
    """Why a run ended.

    Attributes
    ----------
    COMPLETED
        The requested number of samples was taken (state FINISHED).
    ENDED
        END was requested before that (state FINISHED).
    INTERLOCK
        An interlock tripped: output over its limit, input out of range, a
        non-finite reading (state FAULTED).
    RIG_FAULT
        The rig reported a fault or stopped answering (state FAULTED).
    WATCHDOG
        The sampling loop stalled longer than the watchdog allows (state FAULTED).
    ERROR
        An unexpected exception in an identifier, a recorder or a subscriber
        (state FAULTED).
    ABORTED
        :meth:`~thermolab.runner.Experiment.abort`, SIGINT or SIGTERM (state ABORTED).
    """

    COMPLETED = "completed"
    ENDED = "ended"
    INTERLOCK = "interlock"
    RIG_FAULT = "rig_fault"
    WATCHDOG = "watchdog"
    ERROR = "error"
    ABORTED = "aborted"

    @property
    def final_state(self) -> RunState:
        """The terminal state a run ending for this reason reaches.

        Examples
        --------
        >>> EndReason.ENDED.final_state
        <RunState.FINISHED: 'finished'>
        >>> EndReason.WATCHDOG.final_state
        <RunState.FAULTED: 'faulted'>
        """
        if self in (EndReason.COMPLETED, EndReason.ENDED):
            return RunState.FINISHED
        if self is EndReason.ABORTED:
            return RunState.ABORTED
        return RunState.FAULTED


_TERMINAL = frozenset({RunState.FINISHED, RunState.FAULTED, RunState.ABORTED})

_TRANSITIONS: dict[RunState, frozenset[RunState]] = {
    RunState.IDLE: frozenset({RunState.RUNNING, RunState.ABORTED}),
    RunState.RUNNING: frozenset({RunState.ENDING, RunState.FAULTED, RunState.ABORTED}),
    RunState.ENDING: frozenset({RunState.FINISHED, RunState.FAULTED, RunState.ABORTED}),
    RunState.FINISHED: frozenset(),
    RunState.FAULTED: frozenset(),
    RunState.ABORTED: frozenset(),
}


class RunStateMachine:
    """The current :class:`RunState` and its legal transitions (thread-safe).

    Parameters
    ----------
    name : str, optional
        Used in error messages (default ``"run"``).

    Examples
    --------
    >>> sm = RunStateMachine()
    >>> sm.transition(RunState.RUNNING)
    <RunState.IDLE: 'idle'>
    >>> sm.state
    <RunState.RUNNING: 'running'>
    >>> sm.transition(RunState.FINISHED)
    Traceback (most recent call last):
    ...
    thermolab.errors.RunStateError: run: illegal transition running -> finished (allowed: ...)
    """

    def __init__(self, name: str = "run") -> None:
        self._name = name
        self._state = RunState.IDLE
        self._lock = threading.Lock()

    @property
    def state(self) -> RunState:
        """The current state."""
        return self._state

    def can(self, new: RunState) -> bool:
        """Return whether ``new`` is reachable from the current state in one step.

        Parameters
        ----------
        new : RunState
            The candidate next state.

        Returns
        -------
        bool
            ``True`` if :meth:`transition` to ``new`` would succeed now.
        """
        return new in _TRANSITIONS[self._state]

    def transition(self, new: RunState) -> RunState:
        """Move to ``new``; return the previous state.

        Parameters
        ----------
        new : RunState
            The next state.

        Returns
        -------
        RunState
            The state before the transition.

        Raises
        ------
        RunStateError
            If the transition is not allowed from the current state.
        """
        with self._lock:
            previous = self._state
            allowed = _TRANSITIONS[previous]
            if new not in allowed:
                names = ", ".join(sorted(s.value for s in allowed)) or "none, the run is over"
                raise RunStateError(
                    f"{self._name}: illegal transition {previous.value} -> {new.value} "
                    f"(allowed: {names})"
                )
            self._state = new
            return previous

    def __repr__(self) -> str:
        return f"<RunStateMachine {self._name!r} {self._state.value}>"
