"""The experiment runner: samples a rig, applies inputs, feeds identifiers.

See :class:`Experiment` (one run), :mod:`thermolab.runner.events` (what a run
publishes), :mod:`thermolab.runner.event_bus` (how subscribers receive it
without delaying sampling),
:mod:`thermolab.runner.interlocks` (output limits, input range, watchdog),
:mod:`thermolab.runner.recorder` (incremental CSV records),
:mod:`thermolab.runner.state` (the run's state machine) and
:mod:`thermolab.runner.methods` (online identifiers from a method list and
settings; imported on its own because it loads the compiled kernels).
"""

from thermolab.runner.closed_loop import ControlLoop, adaptive_tuner, estimate_trust
from thermolab.runner.control_requests import LoopCommands, closed_loop_channels
from thermolab.runner.event_bus import EventBus, Subscription
from thermolab.runner.events import (
    EstimateEvent,
    Event,
    FaultEvent,
    SampleEvent,
    StateEvent,
)
from thermolab.runner.experiment import (
    Experiment,
    IdentifierLike,
    InputSignal,
    MethodResult,
    RunResult,
)
from thermolab.runner.further import extra_channels, further_channels
from thermolab.runner.interlocks import Interlocks, Watchdog
from thermolab.runner.pair import IOPair, check_pair, pair_choices
from thermolab.runner.recorder import CSV_COLUMNS, CsvRecorder, Recorder
from thermolab.runner.state import EndReason, RunState, RunStateMachine
from thermolab.runner.termination import Terminated, interrupt_signal, termination_signals

__all__ = [
    "CSV_COLUMNS",
    "ControlLoop",
    "CsvRecorder",
    "EndReason",
    "EstimateEvent",
    "Event",
    "EventBus",
    "Experiment",
    "FaultEvent",
    "IOPair",
    "IdentifierLike",
    "InputSignal",
    "Interlocks",
    "LoopCommands",
    "MethodResult",
    "Recorder",
    "RunResult",
    "RunState",
    "RunStateMachine",
    "SampleEvent",
    "StateEvent",
    "Subscription",
    "Terminated",
    "Watchdog",
    "adaptive_tuner",
    "check_pair",
    "closed_loop_channels",
    "estimate_trust",
    "extra_channels",
    "further_channels",
    "interrupt_signal",
    "pair_choices",
    "termination_signals",
]
