"""Runs on remote rigs: the same START, END and inputs, carried out by the rig's host.

:class:`RemoteRuns` sits beside the lab's :class:`~thermolab.lab.runs.RunService`
(which still stores, reads and lists every run): the lab sends a remote rig's
START, END and inputs here (``rig_id in lab.remote_rigs``, a set lookup, so
that an in-process START crosses no new module; tests/lab/test_start_path.py).
A remote rig's START is decided exactly as an in-process one
(the same request check, the same locked transaction of the controller's
turn, the same run row) and then sent to the host (``StartRun``), whose
runner samples the rig with its own interlocks. The samples come back
through :class:`~thermolab.lab.agents.hub.AgentHub` (stored there), are
told to the live stream as runner events, and the host's ``RunEnded``
stores the run's end. A turn that ends ENDs the run as it does in-process;
if the link is down the host ENDs it by itself after its grace.

The identification methods run in the lab, on the samples as they are
stored (:mod:`.estimates`): live estimates and stored results as in-process.

A closed-loop START is checked as in-process (:func:`~thermolab.lab.runs.control.build_control_loop`
on the rig as published, its channels declared with the run) and its request
sent with ``StartRun``: the host's runner drives the PID, so the loop goes on
while the link is lost (within the grace, as any run). The loop's commands
are checked and recorded as in-process (:func:`~thermolab.lab.runs.commands.send_command`
with a :class:`~.loop.RemoteLoop`) and sent to the host; the loop's channels
come back with the samples, its state with the heartbeats, and the
controller's end with ``RunEnded`` (stored as an in-process run's end).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from sqlalchemy import select

from thermolab.agent.protocol import (
    LINK_LOST,
    OWNER_GONE,
    EndRun,
    RunEnded,
    SampleBatch,
    SetInput,
    StartRun,
)
from thermolab.errors import (
    AccessDeniedError,
    HostOfflineError,
    NoRunError,
    NotFoundError,
    RunInProgressError,
    ThermoLabError,
)
from thermolab.lab.access import AccessService
from thermolab.lab.access.queries import SERVER_STOPPED
from thermolab.lab.accounts.users import Principal
from thermolab.lab.agents.estimates import RemoteIdentification
from thermolab.lab.agents.health import HEALTH_FAULT
from thermolab.lab.agents.hub import AgentHub
from thermolab.lab.agents.loop import RemoteLoop, commanded_request
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import Command, Run, RunStatus
from thermolab.lab.rigs.devices import DeviceHub
from thermolab.lab.runs import RunRecord, RunService
from thermolab.lab.runs.commands import loop_state, send_command
from thermolab.lab.runs.control import ControlRequest, build_control_loop
from thermolab.lab.runs.ending import (
    EndCause,
    RunEnd,
    host_end_words,
    save_end,
    status_of,
    stored_timing,
)
from thermolab.lab.runs.export import RunExport
from thermolab.lab.runs.request import RUN_SETTINGS, RunRequest
from thermolab.lab.runs.starting import plan_on_rig, plan_start, store_start
from thermolab.lab.runs.store import RunStore
from thermolab.rigs import RigInfo
from thermolab.runner import (
    ControlLoop,
    EndReason,
    Event,
    LoopCommands,
    SampleEvent,
    extra_channels,
)
from thermolab.runner.pair import STANDARD_INPUT, STANDARD_OUTPUT, IOPair

__all__ = ["RemoteRuns"]

log = logging.getLogger(__name__)


@dataclass
class _RemoteRun:
    run_id: int
    control_session: int
    identification: RemoteIdentification
    experiment: RemoteLoop  # what the closed-loop commands act on (send_command's)
    ended: threading.Event = field(default_factory=threading.Event)
    stopped_by: str | None = None
    away: str | None = None  # the lab ENDed it for its host's absence (the fault's words)


class RemoteRuns:
    """The runs of remote rigs, carried out by their hosts.

    Parameters
    ----------
    runs : RunService
        The lab's run service (it reads the runs back).
    agents : AgentHub
        The links to the hosts.
    db, config, clock, access, devices
        The lab's.
    on_finished, on_run, on_event
        As :class:`RunService`'s: the lab's hooks.
    """

    def __init__(
        self,
        runs: RunService,
        agents: AgentHub,
        *,
        db: Database,
        config: LabConfig,
        clock: LabClock,
        access: AccessService,
        devices: DeviceHub,
        on_finished: Callable[[str], None],
        on_run: Callable[[str, str, RunRecord], None] | None = None,
        on_event: Callable[[str, int, Event], None] | None = None,
    ) -> None:
        self._runs = runs
        self._agents = agents
        self._config = config
        self._clock = clock
        self._access = access
        self._hub = devices
        self._db = db
        self._store = RunStore(db)
        self._on_finished = on_finished
        self._on_run = on_run
        self._on_event = on_event
        self._remote: dict[str, _RemoteRun] = {}
        agents.on_samples = self._samples
        agents.on_run_ended = self._run_ended
        runs.remote_loop = self._loop_of_run

    def start(self, rig_id: str, who: Principal, request: RunRequest) -> RunRecord:
        """START on a remote rig: checked and stored as in-process, then sent to its host.

        Raises
        ------
        ConflictError
            When the rig's host is offline.
        GainRangeError, SetpointRangeError, NoOutputUnitError
            For a closed-loop request the rig cannot take (as in-process).
        RunInProgressError
            If a run is still going on the rig.
        """
        start = plan_start(self._config, self._hub, rig_id, request)
        info, fan = self._rig(rig_id)
        loop = None
        channels = start.channels
        if request.control is not None:
            # Checked as in-process, before anything is stored; the host builds it again.
            loop = self._loop(request.control, request.dt, request.samples, info)
        channels = (*channels, *extra_channels(None, info, loop, fan=fan))  # as the host records
        with self._hub.locked(rig_id):
            going = self._remote.get(rig_id)
            if going is not None:
                raise RunInProgressError(f"run {going.run_id} is still going on rig {rig_id!r}")
            if not self._agents.online(rig_id):
                raise HostOfflineError(f"the host of rig {rig_id!r} is offline; try again later")
            run_id, control_id = store_start(
                self._config, self._access, rig_id, who, start, channels
            )
            pair = IOPair(request.input, request.output)  # checked by plan_start
            identification = RemoteIdentification(start.plan.identifiers, pair.units(info), pair)
            commands = RemoteLoop(run_id, loop, info, fan, lambda c: self._agents.send(rig_id, c))
            self._remote[rig_id] = _RemoteRun(run_id, control_id, identification, commands)
            self._hub.claim(rig_id)
            self._agents.send(
                rig_id,
                StartRun(
                    run=run_id,
                    dt=request.dt,
                    samples=request.samples,
                    signal=request.signal,
                    input=request.setpoint,
                    control=request.control,
                    pair=None if pair.standard else (pair.input, pair.output),
                ),
            )
        record = self._runs.record(run_id)
        if self._on_run is not None:
            self._on_run(rig_id, "started", record)
        return record

    def stop(self, rig_id: str, who: Principal) -> RunRecord:
        """END the rig's run (its controller or a teacher): sent to its host.

        Raises
        ------
        ConflictError
            If no run is going on the rig.
        AccessDeniedError
            If ``who`` neither controls the rig nor is a teacher.
        """
        remote = self._remote.get(rig_id)
        if remote is None:
            raise NoRunError(f"no run is going on rig {rig_id!r}")
        if (
            not who.is_teacher
            and self._access.caller_turn(rig_id, who.user_id) != remote.control_session
        ):
            raise AccessDeniedError(
                f"only the controller of rig {rig_id!r} or a teacher can END its run"
            )
        remote.stopped_by = who.username
        self._agents.send(rig_id, EndRun(run=remote.run_id))
        return self._runs.get(remote.run_id, who)

    def set_input(self, rig_id: str, u: float, *, control_session: int | None = None) -> int | None:
        """Hand an input to the rig's run (see :meth:`RunService.set_input`)."""
        remote = self._remote.get(rig_id)
        if remote is None:
            return None
        if control_session is not None and control_session != remote.control_session:
            return None
        return (
            remote.run_id if self._agents.send(rig_id, SetInput(u=u, run=remote.run_id)) else None
        )

    def command(
        self,
        rig_id: str,
        who: Principal,
        kind: str,
        payload: dict[str, Any],
        act: Callable[[LoopCommands], None],
    ) -> RunRecord:
        """Check, record and send a closed-loop command to the rig's run (as in-process:
        :meth:`RunService.command`, the same errors; ``ConflictError`` if the host is offline).
        """
        run_id = send_command(
            self._access, self._remote.get(rig_id), rig_id, who, kind, payload, act
        )
        return self._runs.get(run_id, who)

    def loop_state(self, rig_id: str) -> dict[str, Any] | None:
        """The control loop of the rig's run as its host last told it, or ``None``."""
        remote = self._remote.get(rig_id)
        if remote is None or remote.experiment.controller is None:
            return None
        told = self._agents.loop(rig_id, remote.run_id)
        if told is None:  # no heartbeat of the run yet: the loop as started
            return loop_state(remote)
        return {**told, "run": remote.run_id}

    def _loop_of_run(self, rig_id: str, run_id: int) -> dict[str, Any] | None:
        """Run ``run_id``'s loop now if it is the rig's run going (``RunOut.control``: the
        loop route's state without its ``run``, as an in-process run's), else ``None``."""
        remote = self._remote.get(rig_id)
        state = self.loop_state(rig_id) if remote is not None and remote.run_id == run_id else None
        return None if state is None else {k: v for k, v in state.items() if k != "run"}

    def control_changed(self, rig_id: str, controller_session: int | None) -> None:
        """END the rig's run when its turn is over (the host ENDs it anyway if unreachable)."""
        remote = self._remote.get(rig_id)
        if remote is not None and remote.control_session != controller_session:
            fault = self._access.snapshot(rig_id).fault
            if fault is not None and fault.startswith(HEALTH_FAULT):
                remote.away = remote.away or fault.removeprefix(HEALTH_FAULT)
            else:
                remote.stopped_by = remote.stopped_by or "end of the turn at the controls"
            self._agents.send(rig_id, EndRun(run=remote.run_id))

    def adopt(self, rig_id: str, run_id: int, control_session: int) -> None:
        """Take over run ``run_id``, going on the rig's host, from a dead owner worker.

        A standby that becomes the owner (docs/fleet.md, "Takeover") knows the
        run from the store: its END, inputs and end of turn work as for a run
        started here, its samples are stored and streamed as they come, and
        its online identifiers are built again from the stored request and
        fed the samples stored so far (a run whose rig's range changed since keeps
        none: its end is then stored without method results). A closed loop's
        checks are built again from its request with the commands recorded since
        folded in: until the host's heartbeat tells it, the loop state is the one
        the lab last commanded.
        """
        identification = self._identification_of(run_id)
        commands = self._adopted_loop(rig_id, run_id)
        with self._hub.locked(rig_id):
            if rig_id not in self._remote:
                self._remote[rig_id] = _RemoteRun(run_id, control_session, identification, commands)
                self._hub.claim(rig_id)

    def _rig(self, rig_id: str) -> tuple[RigInfo, bool]:
        """The rig as published (its spec's, within its published input range); has it a fan."""
        spec = self._config.rig(rig_id).rig_spec
        published = self._hub.published(rig_id)
        info = replace(
            spec.describe(), input_min=published.input_min, input_max=published.input_max
        )
        return info, spec.fan is not None

    @staticmethod
    def _loop(control: ControlRequest, dt: float, samples: int, info: RigInfo) -> ControlLoop:
        times = [k * dt for k in range(samples)]
        return build_control_loop(control, dt, times, info)

    def _adopted_loop(self, rig_id: str, run_id: int) -> RemoteLoop:
        """The closed-loop commands of an adopted run, its loop built again from its request."""
        info, fan = self._rig(rig_id)
        loop = None
        try:
            run, _ = self._store.read(run_id)
            settings = dict((run.meta or {}).get("settings") or {})
            control = settings.get("control")
            if control is not None:
                # ControlRequest.settings() read back: lists were tuples.
                given: dict[str, Any] = {
                    k: tuple(v) if isinstance(v, list) else v for k, v in control.items()
                }
                # The loop as the lab last commanded it (the host tells it once linked here).
                request = commanded_request(ControlRequest(**given), self._commands_of(run_id))
                loop = self._loop(request, settings["dt"], settings["samples"], info)
        except (ThermoLabError, KeyError, TypeError) as exc:
            log.warning("run %s: its control loop cannot be rebuilt: %r", run_id, exc)
        return RemoteLoop(run_id, loop, info, fan, lambda c: self._agents.send(rig_id, c))

    def _commands_of(self, run_id: int) -> list[tuple[str, dict[str, Any] | None]]:
        """The run's recorded commands, ``(kind, payload)`` in the order they were given."""
        with self._db.read() as session:
            rows = session.execute(
                select(Command.kind, Command.payload)
                .where(Command.run_id == run_id)
                .order_by(Command.at, Command.id)
            )
            return [(kind, payload) for kind, payload in rows]

    def _identification_of(self, run_id: int) -> RemoteIdentification:
        try:
            run, _ = self._store.read(run_id)
        except NotFoundError:
            return RemoteIdentification({})
        identification = self._identify_stored(run)
        return identification if identification is not None else RemoteIdentification({})

    def running(self, rig_id: str) -> int | None:
        """The id of the run going on the rig, if any."""
        remote = self._remote.get(rig_id)
        return remote.run_id if remote is not None else None

    def wait(self, rig_id: str, timeout: float | None = None) -> None:
        """Wait until the rig's run (if any) has ended and been stored."""
        remote = self._remote.get(rig_id)
        if remote is not None:
            remote.ended.wait(timeout)

    # -- from the hub ------------------------------------------------------------------------

    def _samples(self, rig_id: str, batch: SampleBatch) -> None:
        last = batch.samples[-1]
        self._hub.note_sample(rig_id, last.u, last.y, of_run=True, channels=last.extra)
        remote = self._remote.get(rig_id)
        on_event = self._on_event
        for s in batch.samples:
            estimates: list[Event] = []
            if remote is not None and remote.run_id == s.run:
                estimates = list(remote.identification.feed(s.k, s.u, s.y, s.extra))
            if on_event is None:
                continue
            event = SampleEvent(
                seq=s.k,
                k=s.k,
                t=s.t,
                t_read=s.t_read,
                u=s.u,
                y=s.y,
                jitter=s.jitter,
                lateness=s.lateness,
                # JSON's null is the runner's NaN (a PID output before the first sample).
                extra={n: math.nan if v is None else v for n, v in (s.extra or {}).items()},
            )
            for each in (event, *estimates):
                on_event(rig_id, s.run, each)

    def _run_ended(self, rig_id: str, ended: RunEnded) -> None:
        remote = self._remote.get(rig_id)
        try:
            reason = EndReason(ended.reason)
        except ValueError:
            reason = EndReason.ERROR
        try:
            run, stored = self._store.read(ended.run)
        except NotFoundError:  # deleted meanwhile: nothing to store (the host may forget it)
            log.warning("rig host %s reported the end of run %s, which is gone", rig_id, ended.run)
            return
        # The host's own END at its grace's end says why: the real cause, even when the lab
        # also asked for the END meanwhile (the turn ended while it was away).
        cause = (
            EndCause.OWNER_GONE
            if ended.message.startswith(OWNER_GONE)
            else EndCause.LINK_LOST
            if ended.message.startswith(LINK_LOST)
            else None
        )
        mine = remote is not None and remote.run_id == ended.run
        words = host_end_words(
            reason,
            ended.message,
            cause=cause,
            away=remote.away if mine and remote is not None else None,
            asked_by=remote.stopped_by if mine and remote is not None else None,
            server_stopped=run.status == RunStatus.INTERRUPTED.value
            and run.end_reason == SERVER_STOPPED,
        )
        if run.rig_id != rig_id:
            log.warning("rig host %s reported the end of run %s of another rig", rig_id, ended.run)
            return
        # Sent again after a lost Ack: storing it twice stores the same end.
        results: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {}
        if remote is not None and remote.run_id == ended.run:
            finals = remote.identification.finish()
            identification = remote.identification
            record = identification.stored_record(RunExport(self._db), ended.run, run.dt)
            results = identification.results(ended.run, record)
            if self._on_event is not None:
                for event in finals:
                    self._on_event(rig_id, ended.run, event)
        elif not stored:
            # A run from before a restart of the lab (stored interrupted then): its
            # methods are identified now, on the samples the host uploaded.
            late = self._identify_stored(run)
            if late is not None:
                late.finish()
                record = late.stored_record(RunExport(self._db), ended.run, run.dt)
                results = late.results(ended.run, record)
        # Judged on the stored samples: all of them are stored by now (the host sends its
        # outbox in order), also for a late end, whose run's samples came before a restart.
        simulated = self._config.rig(rig_id).kind == "sim"
        timing = stored_timing(self._db, ended.run, run.dt, simulated=simulated)
        end = RunEnd(status_of(reason), words, results, timing=timing, control=ended.control)
        save_end(self._db, ended.run, end, self._clock.now())
        if remote is None or remote.run_id != ended.run:
            return  # a run from before a restart of the lab: stored, nothing going
        del self._remote[rig_id]
        self._hub.release(rig_id, left_off=True)  # the host's runner powered the rig off
        if reason is EndReason.RIG_FAULT:
            self._access.report_fault(rig_id, ended.message or "rig fault")
        self._on_finished(rig_id)
        if self._on_run is not None:
            self._on_run(rig_id, "ended", self._runs.record(ended.run))
        remote.ended.set()

    def _identify_stored(self, run: Run) -> RemoteIdentification | None:
        """The run's identifiers, as its START built them, fed its stored samples in order.

        None (logged) when its settings no longer make a plan (the rig's range changed).
        """
        settings = dict((run.meta or {}).get("settings") or {})
        # RunRequest.settings() read back: lists were tuples (w0), absent is the default.
        tuned: dict[str, Any] = {
            name: tuple(value) if isinstance(value, list) else value
            for name in RUN_SETTINGS
            if (value := settings.get(name)) is not None
        }
        try:
            request = RunRequest(
                dt=settings["dt"],
                samples=settings["samples"],
                signal=settings["signal"],
                setpoint=settings["setpoint"],
                methods=tuple(settings["methods"]),
                offset=settings["offset"],
                input=settings.get("input") or STANDARD_INPUT,
                output=settings.get("output") or STANDARD_OUTPUT,
                **tuned,
            )
            plan, _ = plan_on_rig(self._config, self._hub, run.rig_id, request)
            info, _ = self._rig(run.rig_id)
        except (ThermoLabError, KeyError, TypeError) as exc:
            log.warning("run %s: its methods cannot be rebuilt to identify it: %r", run.id, exc)
            return None
        pair = IOPair(request.input, request.output)
        identification = RemoteIdentification(plan.identifiers, pair.units(info), pair)
        identification.feed_stored(RunExport(self._db), run.id)
        return identification
