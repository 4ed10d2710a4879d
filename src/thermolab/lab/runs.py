"""Experiment runs on the lab's rigs: START, set point changes, END, and storage.

A run is the paper's application on a shared rig: the controller starts it
(dt, number of samples, a signal or a manual set point, the identification
methods with their settings), may change the input while it runs, and ends
it; otherwise it ends after its samples. The sampling itself is
:class:`thermolab.runner.Experiment`, on the rig's driver, in a worker thread.

Storage: every sample goes to the ``samples`` table through
:class:`DatabaseRecorder`, which the runner calls once per sample; it only
appends to a buffer, and a writer thread inserts the buffer at least once a
second, so a crash of the server loses at most about a second of samples. At
the end the methods' results (final estimate and trajectories) go to
``method_results`` and the run row records how it ended. A run whose server
stopped is marked ``interrupted`` at the next start.

A run belongs to a turn at the controls: when the turn ends (time limit,
client gone, kicked...) the run is ended as by END, so that its data and
estimates are kept. While a run holds a rig, the lab's hub leaves the device
to the runner.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import func, insert, select, update
from sqlalchemy.orm import Session

from thermolab.errors import (
    AccessDeniedError,
    ConflictError,
    InvalidParameterError,
    NotFoundError,
    ThermoLabError,
)
from thermolab.ident.online import OnlineIdentifier, make_identifier
from thermolab.lab.access import AccessService
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import (
    Command,
    ControlSession,
    MethodResultRow,
    RigRow,
    Run,
    RunStatus,
    Sample,
    User,
)
from thermolab.lab.devices import DeviceHub
from thermolab.lab.security import normalize_username
from thermolab.lab.users import Principal
from thermolab.runner import EndReason, Event, EventBus, Experiment, RunResult
from thermolab.runner.methods import build_identifiers, parse_methods
from thermolab.signals import parse_signal
from thermolab.simulation import PAPER_W0

__all__ = [
    "CONVERGENCE_TOL",
    "MAX_DT",
    "MAX_SAMPLES",
    "MIN_DT",
    "OFFSET_MODES",
    "STATS_LAST",
    "DatabaseRecorder",
    "OperatingPoint",
    "RunRecord",
    "RunRequest",
    "RunService",
    "json_safe",
    "method_statistics",
]

log = logging.getLogger(__name__)

#: Most samples a run may ask for.
MAX_SAMPLES = 200_000
#: Shortest and longest sample period of a run, in seconds (the API schema publishes these).
MIN_DT = 0.01
MAX_DT = 3600.0
#: How a run's identifiers may treat the operating point: ``"auto"`` (chosen by the lab,
#: see :meth:`RunService.operating_point`) or one of :mod:`thermolab.ident`'s modes; a
#: number is also accepted (a known ambient output).
OFFSET_MODES = ("auto", "initial", "fit", "none")
#: The paper's tables: statistics over the last 2000 samples, convergence within ±1 %.
STATS_LAST = 2000
CONVERGENCE_TOL = 0.01

# Methods that regress on the output and so have an operating point to handle.
_OFFSET_METHODS = ("lsm", "blockls", "malsm", "wlsm")
# Methods with one estimate per sample or block (a trajectory that converges).
_TRAJECTORY_METHODS = ("blockls", "malsm", "wlsm")


def json_safe(value: Any) -> Any:
    """Return ``value`` with NaN and infinities replaced by ``None`` (JSON has neither).

    Examples
    --------
    >>> json_safe({"K": float("nan"), "W": [1.0, float("inf")]})
    {'K': None, 'W': [1.0, None]}
    """
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value


@dataclass(frozen=True, slots=True)
class RunRequest:
    """What a controller asks for at START (the three panels of the paper).

    Attributes
    ----------
    dt : float
        Sample period, seconds (:data:`MIN_DT` to :data:`MAX_DT`).
    samples : int
        Samples to take, 1 to :data:`MAX_SAMPLES` (END may stop earlier).
    signal : str or None
        Input signal (``step:0:10@10``, ``square:4:6:0.1``...); ``None`` for a
        manual set point.
    setpoint : float or None
        The manual input at START (with no signal; default the safe input).
    methods : tuple of str
        Identification methods (``srm``, ``lsm``, ``blockls``, ``malsm``, ``wlsm``).
    window, block : int or None
        MALSM window and block-LSM block, in samples.
    gamma, pmax : float or None
        WLSM forgetting factor and initial covariance.
    w0 : tuple of float or None
        WLSM initial parameters ``[a0, b0]`` of the first-order model (``[a0,
        b0, c0]`` with ``offset="fit"``, ``c0`` the constant term); ``None`` is
        the paper's ``W0 = [0.96329, 9.9082e-4]``.
    offset : str or float
        How the identifiers treat the operating point: ``"auto"`` (the lab
        chooses ``"initial"`` for a rig at rest and ``"fit"`` for a warm one,
        see :meth:`RunService.operating_point`), ``"initial"``, ``"fit"``,
        ``"none"``, or a number (the known ambient output).
    """

    dt: float
    samples: int
    signal: str | None = None
    setpoint: float | None = None
    methods: tuple[str, ...] = ("srm", "lsm")
    window: int | None = None
    block: int | None = None
    gamma: float | None = None
    pmax: float | None = None
    w0: tuple[float, ...] | None = None
    offset: str | float = "auto"

    def settings(self) -> dict[str, Any]:
        """The request as stored with the run."""
        return {
            "dt": self.dt,
            "samples": self.samples,
            "signal": self.signal,
            "setpoint": self.setpoint,
            "methods": list(self.methods),
            "window": self.window,
            "block": self.block,
            "gamma": self.gamma,
            "pmax": self.pmax,
            "w0": None if self.w0 is None else list(self.w0),
            "offset": self.offset,
        }


@dataclass(frozen=True, slots=True)
class OperatingPoint:
    """How a run's identifiers handle the operating point, and why (stored with the run).

    Attributes
    ----------
    asked : str or float
        The request's ``offset`` (``"auto"`` unless the user chose).
    used : str, float or None
        The mode the identifiers were built with; ``None`` when no chosen
        method regresses on the output (the step response finds its own
        baseline).
    at_rest : bool or None
        Whether the lab judged the rig at rest at START (``None``: not judged).
    reason : str
        The judgement and the choice, in words (shown to the user).

    Examples
    --------
    >>> OperatingPoint("auto", "fit", False, "run 3 ended 12 s ago").to_dict()["used"]
    'fit'
    """

    asked: str | float
    used: str | float | None
    at_rest: bool | None
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (``asked``, ``used``, ``atRest``, ``reason``)."""
        return {
            "asked": self.asked,
            "used": self.used,
            "atRest": self.at_rest,
            "reason": self.reason,
        }


def method_statistics(
    method: str, identifier: OnlineIdentifier | None, latest: dict[str, Any] | None
) -> dict[str, Any]:
    """The figures of the paper's Tables I/II for one method of a run.

    Parameters
    ----------
    method : str
        The method's name.
    identifier : OnlineIdentifier or None
        The run's identifier (its trajectory gives the statistics of the block
        and recursive methods).
    latest : dict or None
        The method's latest estimate as stored (``Estimate.to_dict()``); the
        one estimate of SRM and LSM.

    Returns
    -------
    dict
        ``{"last", "tol", "K", "tau", "converged_at"}``: ``K`` and ``tau`` are
        ``{"mean", "max", "min"}`` of the valid estimates over the last
        :data:`STATS_LAST` samples (:meth:`thermolab.ident.Trajectory.stats`),
        ``None`` without one; ``converged_at`` is
        :meth:`~thermolab.ident.Trajectory.converged_at` (within ±
        :data:`CONVERGENCE_TOL`) for block and recursive methods and ``None``
        for SRM and LSM, whose one estimate does not converge. SRM and LSM give
        their estimate as mean, max and min.

    Examples
    --------
    >>> method_statistics("lsm", None, {"K": 0.14, "tau": 250.0, "valid": True})["K"]
    {'mean': 0.14, 'max': 0.14, 'min': 0.14}
    """
    out: dict[str, Any] = {
        "last": STATS_LAST,
        "tol": CONVERGENCE_TOL,
        "K": None,
        "tau": None,
        "converged_at": None,
    }
    if method in _TRAJECTORY_METHODS:
        if identifier is None or identifier.n_samples == 0:
            return out
        trajectory = identifier.trajectory()
        stats = trajectory.stats(last=STATS_LAST)
        for name in ("K", "tau"):
            if math.isfinite(stats[name]["mean"]):
                out[name] = stats[name]
        out["converged_at"] = trajectory.converged_at(tol=CONVERGENCE_TOL, last=STATS_LAST)
        return out
    if latest is not None and latest.get("valid"):
        for name in ("K", "tau"):
            value = latest.get(name)
            if isinstance(value, float | int) and math.isfinite(value):
                out[name] = {"mean": float(value), "max": float(value), "min": float(value)}
    return out


@dataclass(frozen=True, slots=True)
class RunRecord:
    """A run as stored, with its live progress when it is running.

    ``results`` maps each method to its latest estimate (a JSON-ready dict,
    ``None`` before the first), why it stopped if it did (``error``) and, once
    the run is over, its statistics (``stats``, see :func:`method_statistics`).
    ``operating_point`` is :meth:`OperatingPoint.to_dict` of the run (``None``
    for runs stored before the lab recorded it).
    """

    id: int
    rig_id: str
    username: str
    user_id: int
    status: str
    dt: float
    samples: int | None
    samples_stored: int
    samples_taken: int
    signal: str | None
    setpoint: float | None
    methods: list[str]
    settings: dict[str, Any]
    started_at: datetime
    ended_at: datetime | None
    end_reason: str | None
    results: dict[str, Any] = field(default_factory=dict)
    operating_point: dict[str, Any] | None = None


class DatabaseRecorder:
    """A runner :class:`~thermolab.runner.Recorder` that stores samples in the database.

    ``write`` (called by the sampling loop) appends to a buffer under a lock;
    a writer thread inserts the buffer every ``interval`` seconds of real
    time; ``close`` inserts the rest before returning.

    Parameters
    ----------
    db : Database
    run_id : int
    interval : float
        Longest time (seconds) a sample waits in memory.
    on_sample : callable, optional
        Called with each sample's ``(u, y)`` (keeps the lab's view of the rig fresh).
    """

    def __init__(
        self,
        db: Database,
        run_id: int,
        *,
        interval: float = 0.5,
        on_sample: Callable[[float, float], None] | None = None,
    ) -> None:
        self._db = db
        self.run_id = run_id
        self._interval = interval
        self._on_sample = on_sample
        self._buffer: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._flush_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.stored = 0
        self.error: BaseException | None = None

    def open(self) -> None:
        """Start the writer thread."""
        self._thread = threading.Thread(
            target=self._loop, name=f"thermolab-run-{self.run_id}-writer", daemon=True
        )
        self._thread.start()

    def write(
        self, k: int, t: float, u: float, y: float, t_read: float, jitter: float, lateness: float
    ) -> None:
        """Queue one sample for the database (never blocks on it)."""
        if self.error is not None:
            # The store failed: stop the run rather than lose samples silently.
            raise ThermoLabError(f"cannot store the run's samples: {self.error}")
        with self._lock:
            self._buffer.append({"run_id": self.run_id, "k": k, "t": t, "u": u, "y": y})
        if self._on_sample is not None:
            self._on_sample(u, y)

    def flush(self) -> int:
        """Insert the buffered samples now; return how many."""
        with self._flush_lock:
            with self._lock:
                rows, self._buffer = self._buffer, []
            if not rows:
                return 0
            with self._db.write() as session:
                session.execute(insert(Sample), rows)
                session.execute(
                    update(Run)
                    .where(Run.id == self.run_id)
                    .values(samples_stored=Run.samples_stored + len(rows))
                )
            self.stored += len(rows)
            return len(rows)

    def close(self) -> None:
        """Stop the writer and store what is left (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self.flush()

    def _loop(self) -> None:
        while not self._stop.wait(self._interval):
            try:
                self.flush()
            except Exception as exc:  # kept, and raised in the sampling loop by write()
                self.error = exc
                log.exception("run %s: storing samples failed", self.run_id)
                return


@dataclass
class _Active:
    run_id: int
    rig_id: str
    control_session: int
    experiment: Experiment
    identifiers: dict[str, OnlineIdentifier]
    thread: threading.Thread | None = None
    stopped_by: str | None = None


class RunService:
    """Starts, stops, stores and lists runs.

    Parameters
    ----------
    db : Database
    clock : LabClock
    access : AccessService
    hub : DeviceHub
    config : LabConfig
        The rigs' cool-down policies (they say when a rig counts as at rest).
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
        self._active: dict[str, _Active] = {}
        self._lock = threading.Lock()

    # -- control -------------------------------------------------------------------------

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
        ConflictError
            If a run is already going on the rig, or the rig has no device.
        """
        published = self._hub.published(rig_id)
        limits = (published.input_min, published.input_max)
        experiment_args = self._check(request, limits)
        methods = parse_methods(request.methods)
        driver = self._hub.driver(rig_id)
        if driver is None:
            raise ConflictError(f"rig {rig_id!r} has no device attached; a run needs one")
        with self._lock:
            if rig_id in self._active:
                raise ConflictError(f"a run is already going on rig {rig_id!r}; END it first")
        point = self.operating_point(rig_id, request.offset, methods)
        options: dict[str, dict[str, Any]] = {
            m: {"offset": point.used} for m in methods if m in _OFFSET_METHODS
        }
        settings = request.settings()
        if "wlsm" in methods:
            w0 = list(PAPER_W0) if request.w0 is None else list(request.w0)
            options["wlsm"]["w0"] = w0
            settings["w0"] = w0
        identifiers = build_identifiers(
            methods,
            request.dt,
            window=request.window,
            block=request.block,
            gamma=request.gamma,
            pmax=request.pmax,
            options=options,
        )

        def begin(session: Session, rig: RigRow, control: ControlSession, now: datetime) -> int:
            running = session.scalar(
                select(Run.id).where(Run.rig_id == rig.id, Run.status == RunStatus.RUNNING.value)
            )
            if running is not None:
                raise ConflictError(f"run {running} is already going on rig {rig.id!r}")
            run = Run(
                rig_id=rig.id,
                user_id=who.user_id,
                control_session_id=control.id,
                status=RunStatus.RUNNING.value,
                dt=request.dt,
                n_samples=request.samples,
                signal=request.signal,
                setpoint=request.setpoint,
                methods=list(identifiers),
                meta={
                    "settings": settings,
                    "username": who.username,
                    "operating_point": point.to_dict(),
                },
                started_at=now,
                samples_stored=0,
            )
            session.add(run)
            session.flush()
            session.add(_command(rig.id, control, who, now, "run_start", None, run.id, settings))
            return run.id

        run_id, control_id = self._access.within_control(rig_id, who, "start a run", begin)
        recorder = DatabaseRecorder(
            self._db, run_id, on_sample=lambda u, y: self._hub.note_sample(rig_id, u, y)
        )
        experiment = Experiment(
            driver,
            request.dt,
            request.samples,
            identifiers=identifiers,
            recorder=recorder,
            events=EventBus(),
            **experiment_args,
        )
        active = _Active(run_id, rig_id, control_id, experiment, identifiers)
        with self._lock:
            self._active[rig_id] = active
        record = self.get(run_id, who)
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
        experiment.start()
        active.thread = threading.Thread(
            target=self._finish, args=(active,), name=f"thermolab-run-{run_id}-end", daemon=True
        )
        active.thread.start()
        return record

    def stop(self, rig_id: str, who: Principal) -> RunRecord:
        """END the rig's current run (its controller, or a teacher); returns at once.

        Raises
        ------
        AccessDeniedError
            If ``who`` neither controls the rig nor is a teacher.
        ConflictError
            If no run is going on the rig.
        """
        with self._lock:
            active = self._active.get(rig_id)
        if active is None:
            raise ConflictError(f"no run is going on rig {rig_id!r}")
        if not who.is_teacher:
            snap = self._access.snapshot(rig_id)
            if snap.controller is None or snap.controller.user_id != who.user_id:
                raise AccessDeniedError(f"only the controller of rig {rig_id!r} may END its run")
        active.stopped_by = who.username
        active.experiment.end()
        return self.get(active.run_id, who)

    def set_input(self, rig_id: str, u: float) -> int | None:
        """Hand a new input to the rig's run; return the run id (``None``: no run)."""
        with self._lock:
            active = self._active.get(rig_id)
        if active is None:
            return None
        active.experiment.set_input(u)
        return active.run_id

    def control_changed(self, rig_id: str, controller_session: int | None) -> None:
        """END the rig's run if the turn it belongs to has ended."""
        with self._lock:
            active = self._active.get(rig_id)
        if active is not None and active.control_session != controller_session:
            active.stopped_by = active.stopped_by or "end of the turn at the controls"
            active.experiment.end()

    def running(self, rig_id: str) -> int | None:
        """Return the id of the run going on the rig, if any."""
        with self._lock:
            active = self._active.get(rig_id)
        return active.run_id if active is not None else None

    def wait(self, rig_id: str, timeout: float | None = None) -> None:
        """Wait until the rig's run (if any) has ended and been stored."""
        with self._lock:
            active = self._active.get(rig_id)
        if active is not None and active.thread is not None:
            active.thread.join(timeout)

    def shutdown(self, timeout: float = 10.0) -> None:
        """Abort every run (server stopping): actuators safe, runs marked interrupted."""
        with self._lock:
            actives = list(self._active.values())
        for active in actives:
            active.stopped_by = "the server stopped"
            active.experiment.abort("the server stopped")
        for active in actives:
            if active.thread is not None:
                active.thread.join(timeout)

    # -- the operating point ---------------------------------------------------------------

    def operating_point(
        self, rig_id: str, asked: str | float, methods: Sequence[str]
    ) -> OperatingPoint:
        """Decide how a run's identifiers treat the rig's operating point.

        ``"initial"`` (the default of :mod:`thermolab.ident`) takes the first
        sample as the equilibrium at 0 V and removes it. A rig still cooling
        after a previous run (or driven by an input a moment ago) breaks that:
        its first sample is neither an equilibrium nor the output at 0 V, and
        the estimates come out biased or unstable. ``"auto"`` therefore looks at
        the rig first (see :meth:`at_rest`) and takes ``"initial"`` for a rig at
        rest, ``"fit"`` (the constant term estimated with the model) for a warm
        one. An explicit choice is kept; ``"initial"`` on a warm rig is kept with
        a warning in the reason.

        Parameters
        ----------
        rig_id : str
        asked : str or float
            The request's ``offset``.
        methods : sequence of str
            The run's methods (only LSM, block LSM, MALSM and WLSM use an offset).

        Returns
        -------
        OperatingPoint

        Raises
        ------
        InvalidParameterError
            For an explicit offset when no chosen method uses one.
        """
        users = [m for m in methods if m in _OFFSET_METHODS]
        if not users:
            if asked != "auto":
                raise InvalidParameterError(
                    f"offset is a setting of {', '.join(_OFFSET_METHODS)}, none of which is among "
                    f"the methods ({', '.join(methods)}); the step response finds its own baseline"
                )
            return OperatingPoint(
                asked, None, None, "no chosen method uses it (the step response finds its baseline)"
            )
        rest, why = self.at_rest(rig_id)
        if asked == "auto":
            if rest:
                return OperatingPoint(
                    asked,
                    "initial",
                    True,
                    f"initial: the rig is at rest ({why}), so its first sample is the "
                    "equilibrium at the safe input and is removed",
                )
            return OperatingPoint(
                asked,
                "fit",
                False,
                f"fit: the rig is not at rest ({why}), so its first sample is no equilibrium; "
                "the operating point is estimated with the model",
            )
        if asked == "initial" and not rest:
            return OperatingPoint(
                asked,
                asked,
                False,
                f"initial, as asked, although the rig is not at rest ({why}): the model may be "
                "biased or unstable; 'fit' estimates the operating point instead",
            )
        state = "at rest" if rest else "not at rest"
        return OperatingPoint(asked, asked, rest, f"{asked}, as asked (the rig is {state}: {why})")

    def at_rest(self, rig_id: str) -> tuple[bool, str]:
        """Whether the rig rests at its equilibrium at the safe input, and why (in words).

        A rig is *not* at rest when any of these holds, checked in this order:

        1. its input is not the safe input now;
        2. a run on it ended, or an input other than the safe one was applied
           to it, within the last ``cooldown.max_seconds`` (the longest the lab
           ever waits for a rig to cool) — and, when the rig cools down between
           turns, since the current turn began (the cool-down before it settled
           what came earlier);
        3. its latest reading is further than ``cooldown.tolerance`` from its
           ambient (the configured one, or the first reading of the rig powered
           on cold).

        Rule 2 needs no threshold, so a rig taken straight from one run to the
        next is always seen as warm, whatever its output's unit and scale.
        """
        cfg = self._config.rig(rig_id)
        published = self._hub.published(rig_id)
        unit, safe = published.output_unit, published.safe_input
        applied = self._hub.applied(rig_id)
        if applied is not None and applied != safe:
            return False, (
                f"its input is {applied:g} {published.input_unit}, not the safe "
                f"{safe:g} {published.input_unit}"
            )
        now = self._clock.now()
        window = cfg.cooldown.max_seconds
        since = now - timedelta(seconds=window)
        snap = self._access.snapshot(rig_id)
        if cfg.cooldown.enabled and snap.controller is not None:
            since = max(since, snap.controller.started_at)
        with self._db.read() as session:
            ended = session.execute(
                select(Run.id, Run.ended_at)
                .where(Run.rig_id == rig_id, Run.ended_at >= since)
                .order_by(Run.ended_at.desc(), Run.id.desc())
                .limit(1)
            ).first()
            driven = session.execute(
                select(Command.value, Command.at)
                .where(
                    Command.rig_id == rig_id,
                    Command.kind == "input",
                    Command.at >= since,
                    Command.value != safe,
                )
                .order_by(Command.at.desc(), Command.id.desc())
                .limit(1)
            ).first()
        if ended is not None:
            ago = (now - ended.ended_at).total_seconds()
            return False, f"run {ended.id} on it ended {ago:.0f} s ago; it may still be cooling"
        if driven is not None:
            ago = (now - driven.at).total_seconds()
            return False, (
                f"an input of {driven.value:g} {published.input_unit} was applied {ago:.0f} s "
                "ago; it may still be cooling"
            )
        ambient = cfg.cooldown.ambient if cfg.cooldown.ambient is not None else snap.ambient_output
        reading = self._hub.reading(rig_id)
        quiet = f"not driven for {window:g} s"
        if ambient is None or reading is None:
            return True, f"{quiet}; its ambient is not known yet"
        gap = reading[0] - ambient
        tolerance = cfg.cooldown.tolerance
        if abs(gap) > tolerance:
            return False, (
                f"its output {reading[0]:g} {unit} is {abs(gap):g} {unit} from its ambient "
                f"{ambient:g} {unit}, more than the tolerance {tolerance:g} {unit}"
            )
        return True, (
            f"{quiet}, output within {tolerance:g} {unit} of its ambient {ambient:g} {unit}"
        )

    # -- reading -------------------------------------------------------------------------

    def get(self, run_id: int, who: Principal) -> RunRecord:
        """Return one run (a student's own or one that is running; any for a teacher).

        Raises
        ------
        NotFoundError
            If there is no such run.
        AccessDeniedError
            If it belongs to another user and ``who`` is a student.
        """
        with self._db.read() as session:
            run = session.get(Run, run_id)
            if run is None:
                raise NotFoundError(f"no run {run_id}")
            _check_owner(run, who)
        return self.record(run_id)

    def record(self, run_id: int) -> RunRecord:
        """Return one run, whoever owns it (for the lab's own use: the live stream).

        Raises
        ------
        NotFoundError
            If there is no such run.
        """
        with self._db.read() as session:
            run = session.get(Run, run_id)
            if run is None:
                raise NotFoundError(f"no run {run_id}")
            stored = self._stored_results(session, run)
            return self._record(run, {data["method"]: data["result"] for data in stored.values()})

    def list(
        self,
        who: Principal,
        rig_id: str | None = None,
        limit: int = 200,
        *,
        user: str | None = None,
    ) -> list[RunRecord]:
        """Return runs, newest first: a student's own, or everyone's for a teacher.

        Parameters
        ----------
        who : Principal
        rig_id : str, optional
            Only this rig's runs.
        limit : int, optional
            At most this many.
        user : str, optional
            Only this user's runs: anyone for a teacher, only themselves for a student.

        Raises
        ------
        AccessDeniedError
            If a student asks for another user's runs.
        NotFoundError
            If a teacher names a user who does not exist.
        InvalidParameterError
            If ``user`` is not a valid user name.
        """
        query = select(Run).order_by(Run.started_at.desc(), Run.id.desc()).limit(limit)
        if user is not None:
            name = normalize_username(user)
            if not who.is_teacher and name != who.username:
                raise AccessDeniedError(
                    f"students may list only their own runs; ask for user={who.username}"
                )
        if rig_id is not None:
            query = query.where(Run.rig_id == rig_id)
        with self._db.read() as session:
            if user is not None and who.is_teacher:
                owner = session.scalar(select(User.id).where(User.username == name))
                if owner is None:
                    raise NotFoundError(f"no user called {name!r}")
                query = query.where(Run.user_id == owner)
            elif not who.is_teacher:
                query = query.where(Run.user_id == who.user_id)
            return [self._record(run, None) for run in session.scalars(query)]

    def samples(self, run_id: int, who: Principal) -> Iterator[tuple[int, float, float, float]]:
        """Yield ``(k, t, u, y)`` of every stored sample of a run, in order.

        Raises
        ------
        NotFoundError, AccessDeniedError
            As :meth:`get`.
        """
        self.get(run_id, who)
        with self._db.read() as session:
            rows = session.execute(
                select(Sample.k, Sample.t, Sample.u, Sample.y)
                .where(Sample.run_id == run_id)
                .order_by(Sample.k)
                .execution_options(yield_per=2000)
            )
            for row in rows:
                yield (row[0], row[1], row[2], row[3])

    def export(self, run_id: int, who: Principal) -> dict[str, Any]:
        """Return a run with its samples and every method's stored result (JSON-ready)."""
        record = self.get(run_id, who)
        ks, ts, us, ys = [], [], [], []
        for k, t, u, y in self.samples(run_id, who):
            ks.append(k)
            ts.append(t)
            us.append(u)
            ys.append(y)
        with self._db.read() as session:
            run = session.get(Run, run_id)
            methods = {} if run is None else self._stored_results(session, run)
        exported: dict[str, Any] = json_safe(
            {
                "run": record,
                "samples": {"k": ks, "t": ts, "u": us, "y": ys},
                "methods": methods,
            }
        )
        return exported

    # -- internals -------------------------------------------------------------------------

    def _check(self, request: RunRequest, limits: tuple[float, float]) -> dict[str, Any]:
        if not (math.isfinite(request.dt) and MIN_DT <= request.dt <= MAX_DT):
            raise InvalidParameterError(
                f"dt must be between {MIN_DT:g} and {MAX_DT:g} seconds, got {request.dt!r}"
            )
        if not 1 <= request.samples <= MAX_SAMPLES:
            raise InvalidParameterError(
                f"samples must be between 1 and {MAX_SAMPLES}, got {request.samples!r}"
            )
        methods = parse_methods(request.methods)
        _check_offset(request.offset)
        if request.w0 is not None:
            _check_w0(request.w0, request.offset, methods)
        if request.signal is not None and request.setpoint is not None:
            raise InvalidParameterError("give either a signal or a setpoint, not both")
        if request.signal is not None:
            return {"signal": parse_signal(request.signal, limits)}
        if request.setpoint is not None:
            low, high = limits
            if not (math.isfinite(request.setpoint) and low <= request.setpoint <= high):
                raise InvalidParameterError(
                    f"setpoint {request.setpoint!r} is outside the rig's input range "
                    f"[{low:g}, {high:g}]"
                )
            return {"set_point": request.setpoint}
        return {}

    def _stored_results(self, session: Session, run: Run) -> dict[str, dict[str, Any]]:
        """Each method's stored ``{"method", "params", "result"}`` by label, with statistics.

        Runs stored before the lab kept statistics get them here, the first time
        they are read: the method is replayed over the stored samples with its
        stored settings (the identifiers are deterministic, so this is the
        trajectory the run had) and the figures are stored for next time.
        """
        rows = list(
            session.scalars(select(MethodResultRow).where(MethodResultRow.run_id == run.id))
        )
        out = {
            row.label: {"method": row.method, "params": row.params, "result": row.result}
            for row in rows
        }
        missing = [row for row in rows if "stats" not in row.result]
        if not missing or run.status == RunStatus.RUNNING.value:
            return out
        samples: list[tuple[float, float]] = [
            (row[0], row[1])
            for row in session.execute(
                select(Sample.u, Sample.y).where(Sample.run_id == run.id).order_by(Sample.k)
            )
        ]
        filled: dict[int, dict[str, Any]] = {}
        for row in missing:
            try:
                identifier = _replay(row.method, run.dt, row.params, samples)
                stats = method_statistics(row.method, identifier, row.result.get("latest"))
            except ThermoLabError as exc:
                log.warning("run %s: statistics of %s failed: %s", run.id, row.label, exc)
                continue
            result = {**row.result, "stats": json_safe(stats)}
            filled[row.id] = result
            out[row.label]["result"] = result
        if filled:
            with self._db.write() as writer:
                for row_id, result in filled.items():
                    writer.execute(
                        update(MethodResultRow)
                        .where(MethodResultRow.id == row_id)
                        .values(result=result)
                    )
        return out

    def _finish(self, active: _Active) -> None:
        result = active.experiment.wait()
        try:
            if result is not None:
                self._store(active, result)
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

    def _store(self, active: _Active, result: RunResult) -> None:
        now = self._clock.now()
        status = _status_of(result.end_reason)
        if active.stopped_by == "the server stopped":
            status = RunStatus.INTERRUPTED
        reason = result.end_reason.value
        if result.message:
            reason = f"{reason}: {result.message}"
        if result.end_reason is EndReason.ENDED and active.stopped_by:
            reason = f"ended by {active.stopped_by}"
        stored: dict[str, dict[str, Any]] = {}
        for name, method in result.methods.items():
            identifier = active.identifiers.get(name)
            data = method.to_dict(trajectory=True)
            try:
                data["stats"] = method_statistics(name, identifier, data.get("latest"))
            except ThermoLabError as exc:  # the figures are a summary: never lose the run
                log.warning("run %s: statistics of %s failed: %s", active.run_id, name, exc)
            stored[name] = json_safe(data)
        with self._db.write() as session:
            for name, data in stored.items():
                session.add(
                    MethodResultRow(
                        run_id=active.run_id,
                        label=name,
                        method=name,
                        params=json_safe(_params(active.identifiers.get(name))),
                        result=data,
                        created_at=now,
                    )
                )
            stored = session.scalar(
                select(func.count()).select_from(Sample).where(Sample.run_id == active.run_id)
            )
            session.execute(
                update(Run)
                .where(Run.id == active.run_id)
                .values(
                    status=status.value,
                    ended_at=now,
                    end_reason=reason,
                    samples_stored=stored or 0,
                )
            )

    def _record(self, run: Run, stored: dict[str, Any] | None) -> RunRecord:
        with self._lock:
            active = self._active.get(run.rig_id)
        live = active is not None and active.run_id == run.id
        results: dict[str, Any] = {}
        taken = run.samples_stored
        if live and active is not None:
            snapshot = active.experiment.snapshot()
            taken = snapshot.samples
            for name, method in snapshot.methods.items():
                results[name] = json_safe(method.to_dict())
        elif stored is not None:
            for name, result in stored.items():
                results[name] = {k: v for k, v in result.items() if k != "trajectory"}
        return RunRecord(
            id=run.id,
            rig_id=run.rig_id,
            username=str(run.meta.get("username", "")),
            user_id=run.user_id,
            status=run.status,
            dt=run.dt,
            samples=run.n_samples,
            samples_stored=run.samples_stored,
            samples_taken=taken,
            signal=run.signal,
            setpoint=run.setpoint,
            methods=list(run.methods),
            settings=dict(run.meta.get("settings", {})),
            started_at=run.started_at,
            ended_at=run.ended_at,
            end_reason=run.end_reason,
            results=results,
            operating_point=run.meta.get("operating_point"),
        )


def _replay(
    method: str, dt: float, params: dict[str, Any], samples: list[tuple[float, float]]
) -> OnlineIdentifier | None:
    """Run a stored method again over a run's samples (``None`` for SRM and LSM)."""
    if method not in _TRAJECTORY_METHODS:
        return None
    identifier = make_identifier(method, dt, **params)
    for u, y in samples:
        try:
            identifier.update(u, y)
        except ThermoLabError:
            break  # where the run's identifier stopped too
    return identifier


def _check_offset(offset: object) -> None:
    if isinstance(offset, str):
        if offset not in OFFSET_MODES:
            raise InvalidParameterError(
                f"offset must be one of {', '.join(repr(m) for m in OFFSET_MODES)} or a number "
                f"(the known ambient output), got {offset!r}"
            )
        return
    if isinstance(offset, bool) or not isinstance(offset, int | float) or not math.isfinite(offset):
        raise InvalidParameterError(
            f"offset must be one of {', '.join(repr(m) for m in OFFSET_MODES)} or a finite "
            f"number (the known ambient output), got {offset!r}"
        )


def _check_w0(w0: Sequence[float], offset: str | float, methods: Sequence[str]) -> None:
    if "wlsm" not in methods:
        raise InvalidParameterError(
            f"w0 is a setting of wlsm, which is not among the methods ({', '.join(methods)})"
        )
    sizes = (2, 3) if offset == "fit" else (2,)
    if len(w0) not in sizes:
        allowed = (
            "2 entries [a0, b0] or 3 [a0, b0, c0] (c0: the constant term)"
            if offset == "fit"
            else "2 entries [a0, b0] (3, with the constant term c0, only with offset 'fit')"
        )
        raise InvalidParameterError(f"w0 must have {allowed}, got {len(w0)}")
    if any(
        isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) for v in w0
    ):
        raise InvalidParameterError(f"w0 must hold finite numbers, got {list(w0)!r}")


def _status_of(reason: EndReason) -> RunStatus:
    if reason is EndReason.COMPLETED:
        return RunStatus.FINISHED
    if reason in (EndReason.ENDED, EndReason.ABORTED):
        return RunStatus.STOPPED
    return RunStatus.FAILED


def _params(identifier: OnlineIdentifier | None) -> dict[str, Any]:
    return dict(identifier.params) if identifier is not None else {}


def _check_owner(run: Run, who: Principal) -> None:
    # A running run is on show to every watcher of its rig; once over it is its owner's.
    if run.status == RunStatus.RUNNING.value:
        return
    if not who.is_teacher and run.user_id != who.user_id:
        raise AccessDeniedError(f"run {run.id} belongs to another user")


def _command(
    rig_id: str,
    control: ControlSession,
    who: Principal,
    now: datetime,
    kind: str,
    value: float | None,
    run_id: int | None,
    payload: dict[str, Any] | None,
) -> Command:
    return Command(
        rig_id=rig_id,
        control_session_id=control.id,
        run_id=run_id,
        user_id=who.user_id,
        username=who.username,
        at=now,
        kind=kind,
        value=value,
        payload=None if payload is None else json_safe(payload),
        applied=True,
    )
