"""Experiment runs on the lab's rigs: START, set point changes, END.

A run is the paper's application on a shared rig: the controller starts it
(dt, number of samples, a signal or a manual set point, the identification
methods with their settings), may change the input while it runs, and ends
it; otherwise it ends after its samples. The sampling itself is
:class:`thermolab.runner.Experiment`, on the rig's driver, in a worker thread.

A run belongs to a turn at the controls, and the turn covers it: the turn's
time limit does not cut a started run (see :func:`thermolab.lab.access.rules.limit_reached`);
instead START refuses a run longer than the rig's ``max_run_seconds``
(:func:`.request.check_run_length`). When the turn ends otherwise (client gone,
kicked, released...) the run is ended as by END, so that its data and
estimates are kept. While a run holds a rig, the lab's device hub leaves the
device to the runner. Storage is :mod:`.store` (reading back by channel: :mod:`.export`); the
request's checks and its operating point are :mod:`.request`; what a START decides and
stores, the same on a rig host, :mod:`.starting`; what is stored when a run
ends, :mod:`.ending`; what is sent to it while it runs (END, an input, a closed loop's
commands), :mod:`.commands`; reading runs back for the routes, :mod:`.reading`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from thermolab.errors import (
    AccessDeniedError,
    ConflictError,
    PreviousRunEndingError,
    RunInProgressError,
    TurnEndedError,
)
from thermolab.lab.access import AccessService
from thermolab.lab.accounts.users import Principal
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import Run
from thermolab.lab.rigs.devices import DeviceHub
from thermolab.lab.runs.active import ActiveRun
from thermolab.lab.runs.commands import end_run, hand_input, loop_state, send_command
from thermolab.lab.runs.control import build_control_loop
from thermolab.lab.runs.ending import SERVER_STOPPED, end_of_run, save_end
from thermolab.lab.runs.export import RunExport
from thermolab.lab.runs.reading import RunReading
from thermolab.lab.runs.recorder import DatabaseRecorder, ride_out
from thermolab.lab.runs.request import RunRequest
from thermolab.lab.runs.starting import plan_start, store_start
from thermolab.lab.runs.store import RunRecord, RunStore, record_of
from thermolab.runner import (
    EndReason,
    Event,
    EventBus,
    Experiment,
    IOPair,
    LoopCommands,
    RunResult,
    extra_channels,
)

__all__ = ["RunService"]

log = logging.getLogger(__name__)

# How long a START waits for the previous turn's run to store its end (seconds), beyond
# the quarter of that run's period the runner may take to notice its END.
HANDOVER_WAIT = 30.0


class RunService(RunReading):
    """Starts, stops and stores runs; lists them (:class:`~.reading.RunReading`).

    Parameters
    ----------
    db : Database
    clock : LabClock
    access : AccessService
    hub : DeviceHub
    config : LabConfig
        The rigs' limits (``max_run_seconds``) and the twins' speed-up.
    on_finished : callable
        Called with the rig id after a run has ended and been stored (the lab
        hands the rig back to the hub).
    on_run : callable, optional
        Called with ``(rig_id, "started" | "ended", record)``.
    on_event : callable, optional
        Called with ``(rig_id, run_id, event)`` for every runner event
        (:class:`~thermolab.runner.SampleEvent`, ``EstimateEvent``...), on a
        thread of the run's own; a failure there never stops the run.
    """

    def __init__(
        self,
        db: Database,
        clock: LabClock,
        access: AccessService,
        hub: DeviceHub,
        config: LabConfig,
        on_finished: Callable[[str], None],
        *,
        on_run: Callable[[str, str, RunRecord], None] | None = None,
        on_event: Callable[[str, int, Event], None] | None = None,
    ) -> None:
        self._db = db
        self._clock = clock
        self._access = access
        self._hub = hub
        self._config = config
        self._on_finished = on_finished
        self._on_run = on_run
        self._on_event = on_event
        self._active: dict[str, ActiveRun] = {}
        # Every run's ending thread until it has returned: after a run leaves
        # _active its thread still announces the end (database reads), and the
        # lab must not close the database under it.
        self._ending: set[threading.Thread] = set()
        self._lock = threading.Lock()

        self._store = RunStore(db)
        self._export = RunExport(db)
        self.handover_wait = HANDOVER_WAIT
        #: Called by START at its decision points (``"start:arrived"``, before the rig's
        #: transaction; ``"start:committed"``, after it, under the rig's hub lock) so that a
        #: test can force any interleaving with the end of a turn (tests/lab/test_fail_closed.py).
        self.checkpoint: Callable[[str], None] = lambda point: None  # straight through
        #: ``(rig_id, run_id)`` -> the control loop of that run if it is going on a rig host
        #: (``ControlLoop.to_dict``, as the host last told it): set by the lab's remote runs.
        self.remote_loop: Callable[[str, int], dict[str, Any] | None] = lambda rig, run: None

    @property
    def stored_samples(self) -> RunExport:
        """The runs' samples read back (the live replay pages through them)."""
        return self._export

    def start(self, rig_id: str, who: Principal, request: RunRequest) -> RunRecord:
        """START a run on the rig ``who`` controls.

        Raises
        ------
        NotFoundError
            For an unknown rig.
        AccessDeniedError
            If ``who`` does not control the rig.
        InvalidParameterError
            For a bad dt, sample count, signal, set point, method or setting.
            Also for a run longer than the rig's ``max_run_seconds`` (the message
            gives the longest run allowed).
        TurnEndedError
            If the caller's turn ended while the START was being decided (409
            ``turn_ended``: before its transaction, or after it and before the
            first sample, when the run is aborted).
        RunInProgressError
            If a run of the caller's turn is already going.
        PreviousRunEndingError
            If the previous turn's run is still ending after the hand-over wait.
        ConflictError
            If the rig has no device.
        """
        self._config.rig(rig_id)  # an unknown rig is a 404, before anything reads its device
        start = plan_start(self._config, self._hub, rig_id, request)
        plan = start.plan
        driver = self._hub.driver(rig_id)
        if driver is None:
            raise ConflictError(
                f"rig {rig_id!r} has no device attached; a run needs one", case="rig_no_device"
            )
        loop = None
        if request.control is not None:
            # Checked before anything is stored: ranges, set point, output unit.
            times = (np.arange(request.samples, dtype=np.float64) * request.dt).tolist()
            loop = build_control_loop(request.control, request.dt, times, driver.describe())
        arrived_in = self._access.caller_turn(rig_id, who.user_id)  # the turn the START came in
        self.checkpoint("start:arrived")
        if arrived_in is not None:  # without a turn START is refused (403) below
            self._await_previous_turn(rig_id, arrived_in)
        channels = (*start.channels, *extra_channels(driver, driver.describe(), loop))

        # START and the end of a turn are one decision: the lab reconciles a rig (and
        # ends its run when the turn is over) under the hub's lock for that rig, so
        # holding it from the check of control to the run's registration means a turn
        # that ends meanwhile is seen either here (the run is aborted before it
        # starts) or by that reconcile, after the run is registered (it is ENDed).
        with self._hub.locked(rig_id):
            going = self._going(rig_id)
            if going is not None and arrived_in is not None:  # else: 403 just below
                if going.control_session == arrived_in:
                    raise RunInProgressError(
                        f"run {going.run_id} of your turn is already going on rig {rig_id!r}; "
                        "END it first"
                    )
                raise self._still_ending(rig_id, going)
            try:
                run_id, control_id = store_start(
                    self._config, self._access, rig_id, who, start, channels
                )
            except AccessDeniedError:
                if arrived_in is None:
                    raise  # the caller had no turn: not allowed, not a lost race
                raise self._access.turn_ended_error(rig_id, arrived_in) from None
            self.checkpoint("start:committed")
            recorder = DatabaseRecorder(
                self._db,
                run_id,
                on_sample=lambda u, y: self._hub.note_sample(rig_id, u, y, of_run=True),
                channels=channels,
            )
            experiment = Experiment(
                driver,
                request.dt,
                request.samples,
                identifiers=plan.identifiers,
                recorder=recorder,
                events=EventBus(),
                controller=loop,
                pair=IOPair(request.input, request.output),
                **plan.inputs,
            )
            active = ActiveRun(run_id, rig_id, control_id, experiment, plan.identifiers)
            if self._access.desired(rig_id)[1] != control_id:
                # The turn ended between our commit and now: the run never starts.
                active.stopped_by = "the end of the turn at the controls"
                experiment.abort("the turn ended before the run started")
                self._finish(active)
                raise TurnEndedError(
                    f"the turn at the controls of rig {rig_id!r} ended while run {run_id} "
                    "was starting; the run was aborted before its first sample"
                )
            record = self.record(run_id)
            if self._on_run is not None:
                # Announced before the first sample, so that watchers see the run begin.
                self._on_run(rig_id, "started", record)
            self._hub.claim(rig_id)
            if self._on_event is not None:
                forward = self._on_event
                experiment.events.subscribe_callback(
                    lambda event: forward(rig_id, run_id, event),
                    maxsize=100_000,
                    name="live",
                    fatal_errors=False,
                )
            try:
                experiment.start()
            except Exception:
                # Fail closed: the run is stored as aborted and the hub takes the
                # device back to its safe state.
                experiment.abort("the run failed to start")
                self._finish(active)
                raise
            active.thread = threading.Thread(
                target=self._finish,
                args=(active,),
                name=f"thermolab-run-{run_id}-end",
                daemon=True,
            )
            with self._lock:
                self._active[rig_id] = active
                self._ending.add(active.thread)
            active.thread.start()
        return record

    def stop(self, rig_id: str, who: Principal) -> RunRecord:
        """END the rig's current run (its controller, or a teacher); returns at once.

        Errors: :func:`.commands.end_run` (``AccessDeniedError``, ``ConflictError``).
        """
        return self.get(end_run(self._access, self._going(rig_id), rig_id, who), who)

    def set_input(self, rig_id: str, u: float, *, control_session: int | None = None) -> int | None:
        """Hand a new input to the rig's run; return the run id (``None``: no run).

        With ``control_session``, only a run of that turn takes it (:func:`.commands.hand_input`).
        """
        return hand_input(self._going(rig_id), u, control_session)

    def command(
        self,
        rig_id: str,
        who: Principal,
        kind: str,
        payload: dict[str, Any],
        act: Callable[[LoopCommands], None],
    ) -> RunRecord:
        """Hand a closed-loop command to the rig's run (mode, set point, gains, fan).

        Checked, applied and recorded by :func:`.commands.send_command`
        (its errors: ``NoRunError``, ``NotClosedLoopError``, ``AccessDeniedError``).
        """
        run_id = send_command(self._access, self._going(rig_id), rig_id, who, kind, payload, act)
        return self.get(run_id, who)

    def loop_state(self, rig_id: str) -> dict[str, Any] | None:
        """The control loop of the rig's run now (``ControlLoop.to_dict``), or ``None``."""
        return loop_state(self._going(rig_id))

    def control_changed(self, rig_id: str, controller_session: int | None) -> None:
        """END the rig's run if the turn it belongs to has ended.

        Called under the hub's lock for the rig (see :meth:`start`). If ENDing
        fails the run is aborted, which puts the actuator at its safe value.
        """
        active = self._going(rig_id)
        if active is None or active.control_session == controller_session:
            return
        active.stopped_by = active.stopped_by or "end of the turn at the controls"
        try:
            active.experiment.end()
        except Exception:
            log.exception("run %s: ENDing at the end of the turn failed; aborting", active.run_id)
            active.experiment.abort("the turn ended")

    def _going(self, rig_id: str) -> ActiveRun | None:
        with self._lock:
            return self._active.get(rig_id)

    def running(self, rig_id: str) -> int | None:
        """Return the id of the run going on the rig, if any."""
        active = self._going(rig_id)
        return active.run_id if active is not None else None

    def _await_previous_turn(self, rig_id: str, turn: int) -> None:
        # Right after a hand-over the previous turn's run is ENDing (the runner notices
        # within a quarter of its period) and storing its end: the new controller's
        # START waits for it instead of getting a 409.
        active = self._going(rig_id)
        if active is None or active.thread is None:
            return
        if turn != active.control_session:
            active.thread.join(self.handover_wait + active.experiment.dt / 4)
            if active.thread.is_alive():
                raise self._still_ending(rig_id, active)

    def _still_ending(self, rig_id: str, active: ActiveRun) -> PreviousRunEndingError:
        return PreviousRunEndingError(
            f"run {active.run_id} of the previous turn at rig {rig_id!r} is still ending "
            f"(waited {self.handover_wait + active.experiment.dt / 4:g} s for it to store its "
            "data); START again in a few seconds"
        )

    def wait(self, rig_id: str, timeout: float | None = None) -> None:
        """Wait until the rig's run (if any) has ended and been stored."""
        active = self._going(rig_id)
        if active is not None and active.thread is not None:
            active.thread.join(timeout)

    def shutdown(self, timeout: float = 60.0) -> None:
        """Abort every run (server stopping): actuators safe, runs marked interrupted.

        Waits for each run's ending thread (it stores the samples and the
        statistics) before returning, so the database is not closed under it:
        the abort itself makes the actuator safe at once, and on a loaded
        machine the storing can take seconds.
        """
        with self._lock:
            actives = list(self._active.values())
        for active in actives:
            active.stopped_by = SERVER_STOPPED
            active.experiment.abort(SERVER_STOPPED)
        with self._lock:
            ending = list(self._ending)
        for thread in ending:
            thread.join(timeout)
            if thread.is_alive():
                log.warning("%s: still storing after %.0f s", thread.name, timeout)

    # -- reading -------------------------------------------------------------------------

    def record(self, run_id: int) -> RunRecord:
        """Return one run, whoever owns it (for the lab's own use: the live stream).

        Raises
        ------
        NotFoundError
            If there is no such run.
        """
        run, stored = self._store.read(run_id)
        return self._record(run, {data["method"]: data["result"] for data in stored.values()})

    # -- internals -------------------------------------------------------------------------

    def _finish(self, active: ActiveRun) -> None:
        try:
            self._end_run(active)
        finally:
            with self._lock:
                self._ending.discard(threading.current_thread())

    def _end_run(self, active: ActiveRun) -> None:
        result = active.experiment.wait()
        try:
            if result is not None:
                self._save_end(active, result)
        except Exception:
            log.exception("run %s: storing the end of the run failed", active.run_id)
        finally:
            with self._lock:
                self._active.pop(active.rig_id, None)
            self._hub.release(active.rig_id)
            if result is not None and result.end_reason is EndReason.RIG_FAULT:
                self._access.report_fault(active.rig_id, result.message or "rig fault")
            self._on_finished(active.rig_id)
            if self._on_run is not None:
                try:
                    self._on_run(active.rig_id, "ended", self.record(active.run_id))
                except Exception:
                    log.exception("run %s: announcing the end failed", active.run_id)

    def _save_end(self, active: ActiveRun, result: RunResult) -> None:
        end = end_of_run(active, result, simulated=self._config.rig(active.rig_id).kind == "sim")
        # A database away at the end (a restart, a failover) must not leave the run
        # "running": try again for as long as a run rides out an outage.
        ride_out(
            lambda: save_end(self._db, active.run_id, end, self._clock.now()),
            f"run {active.run_id}: storing its end",
            1.0,
        )

    def _record(self, run: Run, stored: dict[str, Any] | None) -> RunRecord:
        active = self._going(run.rig_id)
        if active is not None and active.run_id == run.id:
            results, taken, control = active.now()
            return record_of(run, results, taken, control)
        results = {
            n: {k: v for k, v in r.items() if k != "trajectory"} for n, r in (stored or {}).items()
        }
        # A run going on a rig host shows its loop live, as an in-process one; else its end.
        live = self.remote_loop(run.rig_id, run.id) if self._config.rig(run.rig_id).agent else None
        return record_of(run, results, run.samples_stored, live)
