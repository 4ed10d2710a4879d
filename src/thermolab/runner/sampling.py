"""What a run's worker thread does: START, the sampling loop, and every way out.

:class:`SamplingLoop` is the part of :class:`~thermolab.runner.Experiment`
that runs in its thread (kept apart, as :mod:`.control_requests` is, so that
each module stays readable): :meth:`~SamplingLoop._execute` powers the rig on,
takes the samples on their drift-free schedule (:meth:`~SamplingLoop._loop`,
the runner's hot path) and, on every way out — all samples taken, END, a rig
fault, an interlock, the watchdog, an exception, an abort, a signal — puts the
actuator at its safe value before anything else, then finishes the
identifiers, closes the record and builds the :class:`RunResult`. The
experiment's public methods (START, END, abort, inputs) and its construction
stay in :mod:`.experiment`; the attributes below are the experiment's.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from thermolab.errors import RigError, ThermoLabError
from thermolab.records import ChannelSpec
from thermolab.rigs import Clock, Rig, RigInfo, VirtualClock
from thermolab.runner.closed_loop import ControlLoop
from thermolab.runner.event_bus import EventBus
from thermolab.runner.events import (
    NO_EXTRA,
    EstimateEvent,
    FaultEvent,
    SampleEvent,
    StateEvent,
    SupportsToDict,
)
from thermolab.runner.inputs import ChannelSource, IdentifierLike, InputSignal, signal_table
from thermolab.runner.interlocks import Interlocks, Watchdog
from thermolab.runner.pair import IOPair
from thermolab.runner.recorder import Recorder
from thermolab.runner.results import MethodTrack, RunResult
from thermolab.runner.state import EndReason, RunState, RunStateMachine
from thermolab.runner.termination import interrupt_signal

__all__ = ["SamplingLoop"]

_Samples = npt.NDArray[np.float64]

_REQUEST_RANK = {EndReason.ENDED: 0, EndReason.ABORTED: 1, EndReason.WATCHDOG: 2}


class _TripError(Exception):
    """Internal: stop the run for an interlock or the watchdog."""

    def __init__(self, reason: EndReason, source: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason
        self.source = source
        self.message = message


class SamplingLoop:
    """Mixed into :class:`~thermolab.runner.Experiment`: its worker thread's work."""

    # The experiment's state, set by its constructor.
    _rig: Rig
    _info: RigInfo
    _clock: Clock
    _dt: float
    _samples: int
    _late_tolerance: float
    _interlocks: Interlocks
    _recorder: Recorder | None
    _identifiers: dict[str, IdentifierLike]
    _signal: InputSignal | None
    _manual: float | None
    _sources: tuple[ChannelSource, ...]
    _channels: tuple[ChannelSpec, ...]
    _control: ControlLoop | None
    _control_channels: tuple[ChannelSpec, ...]
    _pair: IOPair
    _set_fan: Any
    _fan_request: float | None
    _further_requests: dict[str, float]
    _further_reading: Mapping[str, float]
    _loop_level: float
    events: EventBus
    _machine: RunStateMachine
    _request: tuple[EndReason, str] | None
    _request_lock: threading.Lock
    _k: int
    _t0: float
    _done: threading.Event
    _result: RunResult | None
    _t: _Samples
    _u: _Samples
    _y: _Samples
    _t_read: _Samples
    _jitter: _Samples
    _lateness: _Samples
    _busy: _Samples
    _extra: dict[str, _Samples]
    _late: int
    _missed: int
    _tracks: dict[str, MethodTrack]
    _final: dict[str, SupportsToDict | None]
    _method_errors: dict[str, str]

    def _post_request(self, reason: EndReason, message: str) -> None:
        # The most serious request wins: the watchdog over abort, abort over END.
        with self._request_lock:
            current = self._request
            if current is None or _REQUEST_RANK[reason] > _REQUEST_RANK[current[0]]:
                self._request = (reason, message)

    def _publish_state(
        self, new: RunState, previous: RunState, reason: EndReason | None, message: str
    ) -> None:
        bus = self.events
        if bus.active:
            bus.publish(
                StateEvent(
                    bus.next_seq(), new, previous, None if reason is None else reason.value, message
                )
            )

    def _publish_fault(self, source: str, message: str, *, fatal: bool = True) -> None:
        bus = self.events
        if bus.active:
            bus.publish(FaultEvent(bus.next_seq(), self._k, source, message, fatal))

    def _transition(
        self, new: RunState, reason: EndReason | None = None, message: str = ""
    ) -> None:
        previous = self._machine.transition(new)
        self._publish_state(new, previous, reason, message)

    def _on_watchdog(self, stalled: float) -> None:
        message = (
            f"watchdog: the sampling loop made no progress for {stalled:.1f} s "
            f"(limit {self._interlocks.watchdog:g} s); actuator switched to its safe value"
        )
        self._post_request(EndReason.WATCHDOG, message)
        self._power_off()
        self._publish_fault("watchdog", message)

    def _power_off(self) -> None:
        """Put the actuator at its safe value, whatever happens; close the rig if that fails."""
        for _ in range(3):
            try:
                self._rig.power_off()
                return
            except Exception:
                break
            except BaseException:
                # A second Ctrl-C while making safe: finish making safe first.
                continue
        with contextlib.suppress(BaseException):
            self._rig.close()

    def _execute(self) -> RunResult:
        """START, the sampling loop and the way out; never raises (the error is in the result)."""
        with self._request_lock:
            self._machine.transition(RunState.RUNNING)
        self._publish_state(RunState.RUNNING, RunState.IDLE, None, "")
        reason = EndReason.COMPLETED
        message = ""
        error: BaseException | None = None
        source = ""
        watchdog: Watchdog | None = None
        if self._interlocks.watchdog is not None:
            watchdog = Watchdog(self._interlocks.watchdog, self._on_watchdog)
        try:
            try:
                if self._recorder is not None:
                    self._recorder.open()
                self._rig.power_on()
                if watchdog is not None:
                    watchdog.start()
                self._t0 = self._clock.now()
                reason, message = self._loop(watchdog)
            finally:
                # The safe state comes first, before any bookkeeping can fail.
                self._power_off()
                if watchdog is not None:
                    watchdog.stop()
        except _TripError as trip:
            reason, message, source = trip.reason, trip.message, trip.source
        except RigError as exc:
            reason, message, source, error = EndReason.RIG_FAULT, f"rig fault: {exc}", "rig", exc
        except BaseException as exc:
            error = exc
            if interrupt_signal(exc) is not None:
                reason, message = EndReason.ABORTED, f"interrupted ({exc or type(exc).__name__})"
            else:
                reason, source = EndReason.ERROR, "error"
                message = f"{type(exc).__name__}: {exc}"
        with self._request_lock:
            request = self._request
        if request is not None and request[0] is EndReason.WATCHDOG:
            # Whatever the stalled loop ran into afterwards, the watchdog came first.
            reason, message, source = EndReason.WATCHDOG, request[1], ""
        if source:
            self._publish_fault(source, message)
        self._finish_run(reason, message, error)
        assert self._result is not None
        return self._result

    def _finish_run(self, reason: EndReason, message: str, error: BaseException | None) -> None:
        try:
            self._transition(RunState.ENDING, None, message)
            if reason is not EndReason.ERROR and reason is not EndReason.ABORTED:
                self._finish_identifiers()
        except BaseException as exc:
            if error is None:
                error = exc
                reason = EndReason.ABORTED if interrupt_signal(exc) else EndReason.ERROR
                message = f"{type(exc).__name__} while ending: {exc}"
        finally:
            if self._recorder is not None:
                try:
                    self._recorder.close()
                except Exception as exc:
                    if error is None:
                        error, reason = exc, EndReason.ERROR
                        message = f"the record could not be closed: {exc}"
            signum = interrupt_signal(error) if error is not None else None
            self._result = self._make_result(reason, message, error, signum)
            final = reason.final_state
            previous = self._machine.transition(final)
            self._publish_state(final, previous, reason, message)
            self.events.close()
            self._done.set()

    def _finish_identifiers(self) -> None:
        k = max(self._k - 1, 0)
        bus = self.events
        for name, ident in self._identifiers.items():
            if name in self._method_errors:
                continue
            try:
                estimate = ident.finish()
            except ThermoLabError as exc:
                self._method_failed(name, exc)
                continue
            self._final[name] = estimate
            if estimate is not None and bus.active:
                bus.publish(EstimateEvent(bus.next_seq(), k, name, estimate, True))

    def _method_failed(self, name: str, exc: Exception) -> None:
        message = f"{name}: {exc}"
        self._method_errors[name] = message
        self._publish_fault("identifier", message, fatal=False)

    def _make_result(
        self,
        reason: EndReason,
        message: str,
        error: BaseException | None,
        signum: int | None,
        state: RunState | None = None,
    ) -> RunResult:
        n = self._k
        methods = {
            name: track.result(name, self._final[name], self._method_errors.get(name))
            for name, track in self._tracks.items()
        }
        return RunResult(
            rig=self._info,
            dt=self._dt,
            samples_requested=self._samples,
            t=self._t[:n].copy(),
            u=self._u[:n].copy(),
            y=self._y[:n].copy(),
            t_read=self._t_read[:n].copy(),
            jitter=self._jitter[:n].copy(),
            lateness=self._lateness[:n].copy(),
            busy=self._busy[:n].copy(),
            state=reason.final_state if state is None else state,
            end_reason=reason,
            message=message,
            late=self._late,
            missed=self._missed,
            late_tolerance=self._late_tolerance,
            methods=methods,
            signum=signum,
            error=error,
            extra={name: values[:n].copy() for name, values in self._extra.items()},
            channels=self._channels,
            control=None if self._control is None else self._control.to_dict(),
        )

    def _loop(self, watchdog: Watchdog | None) -> tuple[EndReason, str]:
        """Take the samples; return why sampling stopped (exceptions stop it too)."""
        # Everything the loop touches is a local: this is the runner's hot path.
        rig, info, clock, bus, recorder = (
            self._rig,
            self._info,
            self._clock,
            self.events,
            self._recorder,
        )
        dt, n, t0 = self._dt, self._samples, self._t0
        out_max = self._interlocks.output_max
        out_min = self._interlocks.output_min
        # The pair identified (.pair): a further input driven instead of u, a further output.
        pair = self._pair
        drive = pair.input if pair.drives_further else None
        output_of = None if pair.output == "y" else pair.output_of
        in_min, in_max = pair.input_range(info)
        safe = info.safe_input
        tolerance = self._late_tolerance
        t_arr, u_arr, y_arr = self._t, self._u, self._y
        t_read_arr, jitter_arr, late_arr, busy_arr = (
            self._t_read,
            self._jitter,
            self._lateness,
            self._busy,
        )
        active = [(name, ident, self._tracks[name]) for name, ident in self._identifiers.items()]
        sources = [(spec.name, fn, self._extra[spec.name]) for spec, fn in self._sources]
        control = self._control
        # A loop on a further pair drives that heater from that sensor, not u from y.
        loop_heater = loop_sensor = None
        loop_min, loop_max = -math.inf, math.inf
        if control is not None and control.drives_further:
            loop_heater, loop_sensor = control.heater, control.sensor
            loop_min, loop_max = control.input_range
        q = y_loop = math.nan
        control_arrays = [(spec.name, self._extra[spec.name]) for spec in self._control_channels]
        with_extra = bool(sources) or control is not None
        extra: Mapping[str, float] = NO_EXTRA
        # The signal's values for a block of samples ahead (see _signal_table).
        table: list[float] = []
        table_signal: InputSignal | None = None
        table_start = table_end = 0
        # A virtual clock jumps to the deadline at once; any other clock is waited
        # on in slices so that END and abort are honoured within a quarter period.
        sliced = not isinstance(clock, VirtualClock)
        slice_ = dt / 4.0
        perf = time.perf_counter
        for k in range(n):
            t_k = k * dt
            deadline = t0 + t_k
            now = clock.now()
            if now < deadline:
                if sliced:
                    # A real wait: it must not count as a stall.
                    if watchdog is not None:
                        watchdog.pause()
                    while now < deadline and self._request is None:
                        clock.sleep_until(min(deadline, now + slice_))
                        now = clock.now()
                    if watchdog is not None:
                        watchdog.resume()
                else:
                    clock.sleep_until(deadline)
                    now = clock.now()
            request = self._request
            if request is not None:
                return request
            failure = bus.failure
            if failure is not None:
                raise failure[1]
            wake = perf()
            lateness = now - deadline if now > deadline else 0.0

            reading = rig.read(at=deadline)
            y = float(reading.value)
            self._further_reading = reading.further
            if not (
                (out_max is None or y <= out_max)
                and (out_min is None or y >= out_min)
                and math.isfinite(y)
            ):
                problem = self._interlocks.check_output(y, info.output_unit)
                raise _TripError(EndReason.INTERLOCK, "interlock", f"interlock: {problem}")

            u = self._manual
            if u is None:
                signal = self._signal
                assert signal is not None  # manual is None only while a signal drives
                if signal is not table_signal or k >= table_end:
                    table, table_signal, table_start = signal_table(signal, k, n, dt), signal, k
                    table_end = k + len(table) if table else k
                u = table[k - table_start] if table else float(signal.value(t_k))
            if loop_heater is not None:
                assert control is not None
                assert loop_sensor is not None
                # The further sensor's limit is the rig's own (it faults above it); its
                # heater's range is checked here, as u's is below.
                y_loop = float(reading.further.get(loop_sensor, math.nan))
                if not math.isfinite(y_loop):
                    raise _TripError(
                        EndReason.INTERLOCK, "interlock", f"interlock: {loop_sensor} is {y_loop}"
                    )
                q = control.command(y_loop, self._loop_level, dt, t_k)
                if not loop_min <= q <= loop_max:
                    raise _TripError(
                        EndReason.INTERLOCK,
                        "interlock",
                        f"interlock: {loop_heater} {q:g} outside {loop_min:g}-{loop_max:g}",
                    )
            elif control is not None:
                # The interlock on y was checked above and the input range is checked
                # below: the controller can never override either.
                u = control.command(y, u, dt, t_k)
            if not in_min <= u <= in_max:
                problem = pair.input_problem(u, info)
                raise _TripError(EndReason.INTERLOCK, "interlock", f"interlock: {problem}")
            fan = self._fan_request
            if fan is not None:
                self._fan_request = None
                self._set_fan(fan, at=deadline)
            if self._further_requests:
                with self._request_lock:  # one arriving meanwhile waits for the next sample
                    requested, self._further_requests = self._further_requests, {}
                for name, level in requested.items():
                    rig.set_channel(name, level, at=deadline)
            if loop_heater is not None:  # a closed loop on a further pair: its PID's heater
                q = float(rig.set_channel(loop_heater, q, at=deadline))
            if drive is None:
                u = u_id = float(rig.apply(u, at=deadline))
            else:  # the pair's input takes the signal, u rests
                u_id = float(rig.set_channel(drive, u, at=deadline))
                u = float(rig.apply(safe, at=deadline))
            y_id = y if output_of is None else output_of(y, reading.further)

            t_read = reading.t - t0
            jitter = t_read - t_k
            t_arr[k] = t_k
            u_arr[k] = u
            y_arr[k] = y
            t_read_arr[k] = t_read
            jitter_arr[k] = jitter
            late_arr[k] = lateness
            if with_extra:
                extra = {}
                if control is not None:
                    looped = (
                        control.after(u, y) if loop_heater is None else control.after(q, y_loop)
                    )
                    for (name, values), value in zip(control_arrays, looped, strict=True):
                        values[k] = extra[name] = value
                for name, source, values in sources:
                    values[k] = extra[name] = float(source(t_k, u, y))
                if recorder is not None:
                    recorder.write(k, t_k, u, y, t_read, jitter, lateness, *extra.values())
            elif recorder is not None:
                recorder.write(k, t_k, u, y, t_read, jitter, lateness)
            self._k = k + 1
            if lateness > tolerance:
                self._late += 1
                self._missed += int(lateness // dt)
            if bus.active:
                bus.publish(
                    SampleEvent(bus.next_seq(), k, t_k, t_read, u, y, jitter, lateness, extra)
                )

            for name, ident, track in active:
                try:
                    estimate = ident.update(u_id, y_id)
                except ThermoLabError as exc:
                    self._method_failed(name, exc)
                    active = [entry for entry in active if entry[0] != name]
                    continue
                if estimate is not None:
                    track.add(k, estimate)
                    if bus.active:
                        bus.publish(EstimateEvent(bus.next_seq(), k, name, estimate, False))

            busy_arr[k] = perf() - wake
            if watchdog is not None:
                watchdog.beat()
        return (EndReason.COMPLETED, "")
