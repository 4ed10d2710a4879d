"""Every way out of a run leaves the actuator at its safe value.

Each test drives the heater hard (10 V), leaves the run by one way, and checks
that the twin's actuator holds its safe input, the rig is no longer powered,
the samples taken so far are kept (in the result and the CSV), and the run's
terminal state and end reason say what happened.
"""

from __future__ import annotations

import csv
import os
import signal
import threading
from pathlib import Path
from typing import Any

import pytest

from thermolab.errors import InsufficientExcitationError, RigFaultError
from thermolab.rigs import RigState, VirtualClock
from thermolab.runner import (
    CsvRecorder,
    EndReason,
    Event,
    Experiment,
    FaultEvent,
    Interlocks,
    RunResult,
    RunState,
    SampleEvent,
    Terminated,
    termination_signals,
)

from .conftest import FakeEstimate, HookedTwin, MeanIdentifier


def _assert_safe(rig: HookedTwin) -> None:
    assert rig.applied_input == rig.describe().safe_input == 0.0
    assert not rig.powered


def _csv_rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def _run(rig: HookedTwin, tmp_path: Path, **kwargs: Any) -> tuple[Experiment, RunResult]:
    kwargs.setdefault("set_point", 10.0)
    exp = Experiment(rig, 1.0, kwargs.pop("samples", 100), **kwargs)
    return exp, exp.run()


def test_normal_end(twin: HookedTwin, tmp_path: Path) -> None:
    path = tmp_path / "run.csv"
    _, result = _run(twin, tmp_path, recorder=CsvRecorder(path))
    assert result.state is RunState.FINISHED
    assert result.end_reason is EndReason.COMPLETED
    assert len(_csv_rows(path)) == 100
    _assert_safe(twin)


def test_end_request(twin: HookedTwin, tmp_path: Path) -> None:
    exp = Experiment(twin, 1.0, 100, set_point=10.0)
    twin.hooks[30] = exp.end
    assert exp.run().end_reason is EndReason.ENDED
    _assert_safe(twin)


def test_rig_fault_keeps_the_samples_taken(twin: HookedTwin, tmp_path: Path) -> None:
    twin.inject_fault("lamp driver failed", at=30.0)
    path = tmp_path / "run.csv"
    exp = Experiment(twin, 1.0, 100, set_point=10.0, recorder=CsvRecorder(path))
    faults: list[Event] = []
    sub = exp.events.subscribe()
    result = exp.run()
    faults = [e for e in sub.drain() if isinstance(e, FaultEvent)]
    assert result.state is RunState.FAULTED
    assert result.end_reason is EndReason.RIG_FAULT
    assert "lamp driver failed" in result.message
    assert isinstance(result.error, RigFaultError)
    assert result.samples == 30
    assert len(_csv_rows(path)) == 30
    assert [(f.source, f.fatal) for f in faults] == [("rig", True)]  # type: ignore[union-attr]
    assert twin.state is RigState.FAULTED
    assert twin.applied_input == 0.0


def test_rig_that_cannot_power_on(twin: HookedTwin, tmp_path: Path) -> None:
    twin.inject_fault("stuck relay")
    with pytest.raises(RigFaultError):
        twin.read()
    result = Experiment(twin, 1.0, 10, set_point=10.0).run()
    assert result.end_reason is EndReason.RIG_FAULT
    assert result.samples == 0
    assert "faulted" in result.message
    assert twin.applied_input == 0.0


def test_output_over_its_limit(twin: HookedTwin, tmp_path: Path) -> None:
    path = tmp_path / "run.csv"
    _, result = _run(
        twin,
        tmp_path,
        samples=2000,
        interlocks=Interlocks(output_max=1.0),
        recorder=CsvRecorder(path),
    )
    assert result.end_reason is EndReason.INTERLOCK
    assert result.state is RunState.FAULTED
    assert "above the limit of 1 V" in result.message
    assert result.y.max() <= 1.0  # the offending reading is not recorded as a sample
    assert len(_csv_rows(path)) == result.samples > 0
    _assert_safe(twin)


def test_output_below_its_limit(twin: HookedTwin, tmp_path: Path) -> None:
    _, result = _run(twin, tmp_path, set_point=-10.0, interlocks=Interlocks(output_min=0.5))
    # The box is at ambient (0 V): the very first reading is below 0.5 V.
    assert result.end_reason is EndReason.INTERLOCK
    assert result.samples == 0
    _assert_safe(twin)


def test_reading_that_is_not_a_number(clock: VirtualClock, tmp_path: Path) -> None:
    class NanTwin(HookedTwin):
        def _read_output(self) -> Any:
            reading = super()._read_output()
            return type(reading)(float("nan"), reading.t) if self.reads > 5 else reading

    with NanTwin("paper", clock=clock, output_limit=None) as rig:  # no limit of its own
        _, result = _run(rig, tmp_path)
        assert result.end_reason is EndReason.INTERLOCK
        assert result.samples == 5
        assert "not a number" in result.message
        _assert_safe(rig)


def test_input_out_of_range_is_never_applied(twin: HookedTwin, tmp_path: Path) -> None:
    applied: list[float] = []

    class Runaway:
        def value(self, t: float) -> float:
            return 10.0 if t < 10 else 12.0

    original = twin._apply_input

    def spy(u: float) -> float:
        applied.append(u)
        return original(u)

    twin._apply_input = spy  # type: ignore[method-assign]
    exp = Experiment(twin, 1.0, 100, signal=Runaway())
    result = exp.run()
    assert result.end_reason is EndReason.INTERLOCK
    assert result.samples == 10
    assert "input 12 V is outside the range" in result.message
    assert max(applied) == 10.0
    _assert_safe(twin)


def test_identifier_bug_raises_after_the_safe_state(twin: HookedTwin, tmp_path: Path) -> None:
    class Broken(MeanIdentifier):
        def update(self, u: float, y: float) -> FakeEstimate | None:
            if self.n == 40:
                raise ZeroDivisionError("bug")
            return super().update(u, y)

    path = tmp_path / "run.csv"
    exp = Experiment(
        twin, 1.0, 100, set_point=10.0, identifiers={"b": Broken()}, recorder=CsvRecorder(path)
    )
    with pytest.raises(ZeroDivisionError, match="bug"):
        exp.run()
    result = exp.result
    assert result is not None
    assert result.end_reason is EndReason.ERROR
    assert result.state is RunState.FAULTED
    assert result.message == "ZeroDivisionError: bug"
    assert result.samples == 41
    assert len(_csv_rows(path)) == 41
    _assert_safe(twin)


def test_identifier_that_cannot_estimate_stops_alone(twin: HookedTwin, tmp_path: Path) -> None:
    class NoExcitation(MeanIdentifier):
        def finish(self) -> FakeEstimate | None:
            raise InsufficientExcitationError("the input never changed")

    class Picky(MeanIdentifier):
        def update(self, u: float, y: float) -> FakeEstimate | None:
            if self.n == 10:
                raise InsufficientExcitationError("singular")
            return super().update(u, y)

    exp = Experiment(
        twin,
        1.0,
        50,
        set_point=10.0,
        identifiers={"a": NoExcitation(), "b": Picky(), "ok": MeanIdentifier()},
    )
    sub = exp.events.subscribe()
    result = exp.run()
    assert result.ok
    assert result.samples == 50
    assert result.methods["a"].error == "a: the input never changed"
    assert result.methods["b"].error == "b: singular"
    assert len(result.methods["b"].k) == 10
    assert result.methods["ok"].error is None
    assert result.methods["ok"].final is not None
    faults = [e for e in sub.drain() if isinstance(e, FaultEvent)]
    assert sorted((f.source, f.fatal) for f in faults) == [("identifier", False)] * 2
    _assert_safe(twin)


def test_subscriber_error_stops_the_run(twin: HookedTwin, tmp_path: Path) -> None:
    def broken(event: Event) -> None:
        if isinstance(event, SampleEvent):
            raise KeyError("no such widget")

    exp = Experiment(twin, 1.0, 100, set_point=10.0)
    exp.events.subscribe_callback(broken, name="widget")
    # Hold the loop at sample 5 until the subscriber's thread has failed, so the
    # test does not depend on thread scheduling.
    failed = threading.Event()
    twin.hooks[5] = lambda: [failed.wait(0.01) for _ in range(500) if exp.events.failure is None]
    with pytest.raises(KeyError):
        exp.run()
    result = exp.result
    assert result is not None
    assert result.end_reason is EndReason.ERROR
    assert result.message == "KeyError: 'no such widget'"
    assert result.samples == 6
    _assert_safe(twin)


def test_recorder_failure_stops_the_run(twin: HookedTwin, tmp_path: Path) -> None:
    class FullDisk(CsvRecorder):
        def write(self, *args: Any) -> None:
            if self.rows == 20:
                raise OSError(28, "No space left on device")
            super().write(*args)

    exp = Experiment(twin, 1.0, 100, set_point=10.0, recorder=FullDisk(tmp_path / "x.csv"))
    with pytest.raises(OSError, match="No space left"):
        exp.run()
    assert exp.result is not None
    assert exp.result.end_reason is EndReason.ERROR
    _assert_safe(twin)


def test_watchdog_makes_the_rig_safe_while_the_loop_is_stalled(twin: HookedTwin) -> None:
    release = threading.Event()
    safe_while_stalled: list[float] = []

    class Hangs(MeanIdentifier):
        def update(self, u: float, y: float) -> FakeEstimate | None:
            if self.n == 20:
                # Stalls until the watchdog has acted; record the actuator meanwhile.
                assert dog_tripped.wait(10.0)
                safe_while_stalled.append(twin.applied_input)
                release.set()
            return super().update(u, y)

    exp = Experiment(
        twin,
        1.0,
        100,
        set_point=10.0,
        identifiers={"h": Hangs()},
        interlocks=Interlocks(watchdog=0.1),
    )
    dog_tripped = threading.Event()
    exp.events.subscribe_callback(
        lambda e: dog_tripped.set() if isinstance(e, FaultEvent) else None
    )
    result = exp.run()
    assert release.is_set()
    assert safe_while_stalled == [0.0]  # made safe by the watchdog, not by the loop
    assert result.end_reason is EndReason.WATCHDOG
    assert result.state is RunState.FAULTED
    assert "no progress" in result.message
    assert result.samples == 21
    _assert_safe(twin)


def test_keyboard_interrupt(twin: HookedTwin, tmp_path: Path) -> None:
    path = tmp_path / "run.csv"

    def interrupt() -> None:
        raise KeyboardInterrupt

    twin.hooks[20] = interrupt
    exp = Experiment(twin, 1.0, 100, set_point=10.0, recorder=CsvRecorder(path))
    with pytest.raises(KeyboardInterrupt):
        exp.run()
    result = exp.result
    assert result is not None
    assert result.state is RunState.ABORTED
    assert result.signum == signal.SIGINT
    assert result.samples == 20
    assert len(_csv_rows(path)) == 20
    _assert_safe(twin)


def test_sigterm(twin: HookedTwin, tmp_path: Path) -> None:
    twin.hooks[20] = lambda: os.kill(os.getpid(), signal.SIGTERM)
    exp = Experiment(twin, 1.0, 100, set_point=10.0, recorder=CsvRecorder(tmp_path / "r.csv"))
    # Whatever handler was there before (a rig driver may have installed its own) comes back.
    before = signal.getsignal(signal.SIGTERM)
    with termination_signals(), pytest.raises(Terminated):
        exp.run()
    assert signal.getsignal(signal.SIGTERM) is before
    result = exp.result
    assert result is not None
    assert result.state is RunState.ABORTED
    assert result.signum == signal.SIGTERM
    assert len(_csv_rows(tmp_path / "r.csv")) == result.samples
    _assert_safe(twin)


def test_abort_from_another_thread(twin: HookedTwin) -> None:
    exp = Experiment(twin, 1.0, 100, set_point=10.0, identifiers={"m": MeanIdentifier()})
    aborter = threading.Thread(target=exp.abort, args=("operator pressed stop",))
    twin.hooks[10] = lambda: (aborter.start(), aborter.join())
    result = exp.run()
    assert result.state is RunState.ABORTED
    assert result.message == "operator pressed stop"
    assert result.samples == 11
    assert result.methods["m"].final is None  # aborted: no final estimates
    _assert_safe(twin)


def test_abort_before_start_touches_nothing(twin: HookedTwin) -> None:
    exp = Experiment(twin, 1.0, 100, set_point=10.0)
    exp.abort()
    assert exp.state is RunState.ABORTED
    assert exp.result is not None
    assert exp.result.samples == 0
    assert twin.state is RigState.IDLE


def test_worker_thread_exception_is_kept_in_the_result(twin: HookedTwin) -> None:
    class Broken(MeanIdentifier):
        def update(self, u: float, y: float) -> FakeEstimate | None:
            raise RuntimeError("kaput")

    exp = Experiment(twin, 1.0, 100, set_point=10.0, identifiers={"b": Broken()})
    exp.start()
    result = exp.wait(10.0)
    assert result is not None
    assert result.end_reason is EndReason.ERROR
    assert isinstance(result.error, RuntimeError)
    _assert_safe(twin)
