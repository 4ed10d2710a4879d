"""One experiment run: sample a rig on a drift-free schedule, drive it, identify it live.

:class:`Experiment` is the paper's application without its panels: START
(:meth:`Experiment.run` or :meth:`Experiment.start`) begins recording, the
input comes from a signal or a set point that can change while running,
every sample feeds any set of online identifiers at once, and END
(:meth:`Experiment.end`) closes the test early; otherwise it closes after the
requested number of samples.

The loop, once per sample ``k``:

1. waits until the deadline ``t0 + k·dt`` (computed from the start, never by
   adding up sleeps, so errors never accumulate); a sample taken late is still
   taken, with its lateness recorded — nothing is skipped;
2. reads the output ``y(k)`` and checks it against the interlocks;
3. computes the input ``u(k)`` (the signal at ``k·dt``, or the set point),
   checks its range and applies it; it holds until the next sample, as the
   zero-order hold of eq. 4 assumes;
4. records the sample (memory and the recorder, flushed), publishes it, and
   feeds ``(u(k), y(k))`` to every identifier, publishing their estimates.

On every way out — all samples taken, END, a rig fault, an interlock, the
watchdog, an exception, :meth:`Experiment.abort`, SIGINT/SIGTERM — the rig is
powered off (actuator at its safe value) before anything else happens.
The loop and the ways out are the worker thread's, :mod:`.sampling`; the
closed-loop requests, :mod:`.control_requests`; the checks of the arguments,
:mod:`.arguments`; the further channels' sources, :mod:`.further`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence

import numpy as np

from thermolab.errors import InvalidParameterError, RunStateError
from thermolab.records import RUN_CHANNELS, ChannelSpec
from thermolab.rigs import Rig
from thermolab.runner.arguments import (
    check_channels,
    check_controller,
    check_schedule,
    checked_identifiers,
)
from thermolab.runner.closed_loop import ControlLoop
from thermolab.runner.control_requests import ControlRequests, fan_source
from thermolab.runner.event_bus import EventBus
from thermolab.runner.events import SupportsToDict
from thermolab.runner.further import further_sources
from thermolab.runner.inputs import ChannelSource, IdentifierLike, InputSignal
from thermolab.runner.interlocks import Interlocks
from thermolab.runner.pair import IOPair, check_pair
from thermolab.runner.recorder import Recorder
from thermolab.runner.results import MethodResult, MethodTrack, RunResult
from thermolab.runner.sampling import SamplingLoop
from thermolab.runner.state import EndReason, RunState, RunStateMachine

__all__ = [
    "ChannelSource",
    "Experiment",
    "IdentifierLike",
    "InputSignal",
    "MethodResult",
    "RunResult",
]


class Experiment(ControlRequests, SamplingLoop):
    """One run of an experiment on a rig.

    Parameters
    ----------
    rig : Rig
        The rig to sample; its clock is the run's clock. The caller owns it
        (opens and closes it); the run powers it on at START and off at the end.
    dt : float
        Sample period in seconds (> 0).
    samples : int
        Number of samples requested (>= 1); END may stop the run earlier.
    signal : InputSignal, optional
        The input as a function of time since START (``signal.value(k·dt)``).
    set_point : float, optional
        A constant input instead (manual mode). With neither, the set point
        is the rig's safe input until :meth:`set_input` changes it.
    identifiers : mapping of str to IdentifierLike, optional
        Online identifiers fed every sample, by name (``{"srm": ..., "wlsm": ...}``;
        see :func:`thermolab.runner.methods.build_identifiers`).
    recorder : Recorder, optional
        Receives every sample as it is taken (e.g. :class:`CsvRecorder`).
    interlocks : Interlocks, optional
        Output limits and watchdog (default :class:`Interlocks()`: 10 s watchdog).
    late_tolerance : float, optional
        Lateness in seconds above which a sample counts as late (default ``dt / 10``).
    events : EventBus, optional
        The bus to publish on (default: a new one, :attr:`events`).
    sources : sequence of ChannelSource, optional
        Extra channels recorded with every sample, as ``(ChannelSpec, f)``
        pairs with ``f(t, u, y) -> float`` (a set point, an error signal, a
        second sensor). Their values reach the recorder (after the seven
        standard values, in this order), :attr:`SampleEvent.extra` and
        :attr:`RunResult.extra`. A recorder used with sources must declare the
        same :attr:`channels` (``CsvRecorder(path, channels=exp.channels)``).
    controller : ControlLoop, optional
        A PID on the output (:class:`~thermolab.runner.closed_loop.ControlLoop`).
        In AUTO it computes the input; in MANUAL the signal or the manual
        input drives and the PID tracks it. Its channels (``r, u_pid, e,
        auto``...) come after the standard ones, before the sources'. The
        interlocks and the safe state are checked before and after it, as
        for any input. A loop on a further pair (``heater="q2", sensor="t2"``)
        drives that input from that output; ``u`` is then a disturbance.

    Raises
    ------
    InvalidParameterError
        If ``dt``, ``samples``, ``late_tolerance`` or the set point is invalid,
        or both a signal and a set point are given, or an extra channel's
        name is taken or repeated, or the recorder's channels differ, or the
        controller does not fit the rig (no output unit, set point outside
        the output range).

    Examples
    --------
    >>> from thermolab.rigs import VirtualClock
    >>> from thermolab.rigs.twin import TwinRig
    >>> with TwinRig("paper", clock=VirtualClock()) as rig:
    ...     result = Experiment(rig, dt=1.0, samples=2000, set_point=10.0).run()
    >>> result.end_reason, result.samples, round(float(result.y[-1]), 4)
    (<EndReason.COMPLETED: 'completed'>, 2000, 1.4004)
    >>> rig.applied_input  # the actuator is back at the safe value
    0.0
    """

    def __init__(
        self,
        rig: Rig,
        dt: float,
        samples: int,
        *,
        signal: InputSignal | None = None,
        set_point: float | None = None,
        identifiers: Mapping[str, IdentifierLike] | None = None,
        recorder: Recorder | None = None,
        interlocks: Interlocks | None = None,
        late_tolerance: float | None = None,
        events: EventBus | None = None,
        sources: Sequence[ChannelSource] = (),
        controller: ControlLoop | None = None,
        pair: IOPair | None = None,
    ) -> None:
        late_tolerance = check_schedule(dt, samples, signal, set_point, late_tolerance)
        self._info = rig.describe()
        self._pair = IOPair() if pair is None else check_pair(self._info, pair.input, pair.output)
        check_controller(controller, self._pair)
        # Every run records the rig's further channels (a kit's T2, Q2) after the loop's;
        # set_further() applies a further input at a sample's instant.
        self._further_reading: Mapping[str, float] = {}
        self._further_requests: dict[str, float] = {}
        self._sources = (
            *further_sources(rig, self._info, lambda: self._further_reading),
            *((spec, fn) for spec, fn in sources),
        )
        # A closed-loop run on a rig with a disturbance fan records it (after the loop's
        # channels), and set_fan() applies it at a sample's instant.
        self._set_fan = getattr(rig, "set_fan", None)
        self._fan_request: float | None = None
        if controller is not None and callable(self._set_fan):
            self._sources = (fan_source(rig), *self._sources)
        self._interlocks = interlocks if interlocks is not None else Interlocks()
        self._control = controller
        control_channels: tuple[ChannelSpec, ...] = ()
        self._loop_level = math.nan  # a loop on a further pair's (a kit's q2/t2)
        if controller is not None:
            controller.bind(self._info, self._interlocks, (np.arange(samples) * dt).tolist())
            control_channels = controller.channels()
            if controller.drives_further:  # its heater's level in MANUAL, from its default
                self._loop_level = self._info.inputs[controller.heater].default
        self._control_channels = control_channels
        self._channels = (
            *RUN_CHANNELS,
            *control_channels,
            *(spec for spec, _ in self._sources),
        )
        check_channels(self._channels, recorder)
        self._rig = rig
        self._clock = rig.clock
        self._dt = float(dt)
        self._samples = int(samples)
        self._late_tolerance = float(late_tolerance)
        self._recorder = recorder
        self._identifiers = checked_identifiers(identifiers)
        self._signal = signal
        self._manual: float | None = None
        if signal is None:
            rest = self._pair.rest(self._info) if set_point is None else set_point
            self._manual = self._checked_input(rest)
        self.events = events if events is not None else EventBus()
        self._machine = RunStateMachine("run")
        self._request: tuple[EndReason, str] | None = None
        self._request_lock = threading.Lock()
        self._k = 0
        self._t0 = math.nan
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        self._result: RunResult | None = None
        n = self._samples
        self._t = np.empty(n)
        self._u = np.empty(n)
        self._y = np.empty(n)
        self._t_read = np.empty(n)
        self._jitter = np.empty(n)
        self._lateness = np.empty(n)
        self._busy = np.empty(n)
        self._extra = {spec.name: np.empty(n) for spec in self._channels[len(RUN_CHANNELS) :]}
        self._late = 0
        self._missed = 0
        self._tracks = {name: MethodTrack() for name in self._identifiers}
        self._final: dict[str, SupportsToDict | None] = dict.fromkeys(self._identifiers)
        self._method_errors: dict[str, str] = {}

    # -- properties ----------------------------------------------------------------

    @property
    def rig(self) -> Rig:
        """The rig being sampled."""
        return self._rig

    @property
    def dt(self) -> float:
        """Sample period in seconds."""
        return self._dt

    @property
    def samples(self) -> int:
        """Number of samples requested."""
        return self._samples

    @property
    def state(self) -> RunState:
        """The run's current state."""
        return self._machine.state

    @property
    def channels(self) -> tuple[ChannelSpec, ...]:
        """The run's channels in record order: ``RUN_CHANNELS``, then the sources'."""
        return self._channels

    @property
    def pair(self) -> IOPair:
        """The input/output pair the run identifies."""
        return self._pair

    @property
    def k(self) -> int:
        """Number of samples taken so far."""
        return self._k

    @property
    def set_point(self) -> float | None:
        """The manual input, or ``None`` while a signal drives the rig."""
        return self._manual

    @property
    def result(self) -> RunResult | None:
        """The result once the run is over, else ``None``."""
        return self._result

    # -- control (thread-safe) -----------------------------------------------------------

    def set_input(self, u: float) -> None:
        """Switch to manual input ``u`` (a set point), from the next sample on.

        With a controller, this also switches it to MANUAL (its PID then
        tracks ``u``), unless it drives a further pair (a kit's ``q2``/``t2``):
        ``u`` is then the other heater, a disturbance to the loop.

        Parameters
        ----------
        u : float
            The input, within the rig's input range.

        Raises
        ------
        InvalidParameterError
            If ``u`` is not finite or outside the rig's input range (the input
            in force is unchanged).
        RunStateError
            If the run is already over.
        """
        value = self._checked_input(u)
        self._refuse_when_over("change the input")
        self._manual = value
        if self._control is not None and not self._control.drives_further:
            self._control.request_manual()

    def set_signal(self, signal: InputSignal) -> None:
        """Let ``signal`` drive the input from the next sample on (time since START).

        Parameters
        ----------
        signal : InputSignal
            Anything with ``value(t) -> float``.

        Raises
        ------
        InvalidParameterError
            If ``signal`` has no ``value`` method.
        RunStateError
            If the run is already over.
        """
        if not isinstance(signal, InputSignal):
            raise InvalidParameterError(
                f"a signal needs a value(t) method, got {type(signal).__name__}"
            )
        self._refuse_when_over("change the input")
        self._signal = signal
        self._manual = None
        if self._control is not None and not self._control.drives_further:
            self._control.request_manual()

    def end(self) -> None:
        """END: stop sampling after the current sample and compute the final estimates.

        No effect once the run is ending or over.

        Raises
        ------
        RunStateError
            If the run has not started (there is nothing to end).
        """
        if self._machine.state is RunState.IDLE:
            raise RunStateError("cannot END a run that has not started; START it first")
        self._post_request(EndReason.ENDED, "ended by request")

    def abort(self, message: str = "aborted by request") -> None:
        """Stop at once: actuator safe, no final estimates, state ABORTED.

        A run not yet started is aborted without touching the rig. No effect
        once the run is over.

        Parameters
        ----------
        message : str, optional
            Why (recorded in the result and the state event).
        """
        with self._request_lock:
            if self._machine.state is RunState.IDLE:
                self._machine.transition(RunState.ABORTED)
                self._publish_state(RunState.ABORTED, RunState.IDLE, EndReason.ABORTED, message)
                self._result = self._make_result(EndReason.ABORTED, message, None, None)
                self.events.close()
                self._done.set()
                return
        self._post_request(EndReason.ABORTED, message)

    def wait(self, timeout: float | None = None) -> RunResult | None:
        """Wait for the run to be over; return its result (``None`` on timeout).

        Parameters
        ----------
        timeout : float, optional
            Seconds to wait at most (default: until the end).

        Returns
        -------
        RunResult or None
        """
        self._done.wait(timeout)
        return self._result

    # -- running -----------------------------------------------------------------------------

    def start(self) -> None:
        """START in a worker thread and return at once (for a server).

        Follow with :meth:`wait`. Exceptions end the run (safe state) and are
        kept in ``result.error``; they are not raised.

        Raises
        ------
        RunStateError
            If the run was already started.
        """
        if self._machine.state is not RunState.IDLE or self._thread is not None:
            raise RunStateError(f"cannot START: the run is {self._machine.state.value}")
        # Not a daemon: the interpreter waits for the run's safe end rather than
        # killing it with the actuator driven.
        self._thread = threading.Thread(target=self._execute, name="thermolab-run")
        self._thread.start()

    def run(self) -> RunResult:
        """START and run in the calling thread until the end; return the result.

        Returns
        -------
        RunResult
            Also for a rig fault, an interlock or the watchdog (``state`` FAULTED).

        Raises
        ------
        RunStateError
            If the run was already started.
        KeyboardInterrupt, Terminated
            After the safe state, if the run was interrupted (``result`` is set).
        Exception
            After the safe state, an unexpected error from an identifier, a
            recorder or a subscriber callback (``result`` is set).
        """
        if self._thread is not None:
            raise RunStateError("cannot START: the run was started in a worker thread")
        result = self._execute()
        if result.error is not None and (
            result.end_reason is EndReason.ERROR or result.signum is not None
        ):
            raise result.error
        return result

    def snapshot(self) -> RunResult:
        """Return what has been recorded so far (the result once the run is over).

        Safe to call from any thread while the run goes on (for a watcher that
        joins late: subscribe first, then take the snapshot, and skip events
        whose ``k`` it already has).

        Returns
        -------
        RunResult
            With ``end_reason`` and ``message`` describing the present state.
        """
        if self._result is not None:
            return self._result
        state = self.state
        return self._make_result(
            EndReason.ENDED, f"snapshot while {state.value}", None, None, state
        )

    # -- internals (the worker thread's: thermolab.runner.sampling) ---------------------------

    def _checked_input(self, u: float) -> float:
        try:
            value = float(u)
        except (TypeError, ValueError):
            raise InvalidParameterError(f"the input must be a number, got {u!r}") from None
        problem = self._pair.input_problem(value, self._info)
        if problem is not None:
            raise InvalidParameterError(problem)
        return value

    def _refuse_when_over(self, action: str) -> None:
        state = self._machine.state
        if state.terminal or state is RunState.ENDING:
            raise RunStateError(f"cannot {action}: the run is {state.value}")

    def __repr__(self) -> str:
        return (
            f"<Experiment {self._info.name!r} dt={self._dt:g} "
            f"{self._k}/{self._samples} {self.state.value}>"
        )
