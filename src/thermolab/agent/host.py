"""The rig host's side of a rig: the driver, the runner, the interlocks, the outbox.

:class:`RigHost` does on the rig host what the lab's device hub and run
service do in-process: it holds the rig's driver, powers it as the lab asks,
applies a controller's input, and runs an :class:`~thermolab.runner.Experiment`
(with its interlocks and watchdog) for a START. Every sample and every run's
end goes to the durable :class:`~thermolab.agent.outbox.Outbox` before the
link sees it.

It needs no link to stay safe: when the link is lost (:meth:`link_lost`), a
run in progress is ENDed after ``grace`` seconds (the runner puts the
actuator at its safe value on the way out) and an idle rig is powered off at
once; a lab that never comes back cannot leave a heater on.

A closed-loop run's PID is this runner's (:class:`~thermolab.runner.ControlLoop`,
built from the START's request as the lab builds it), so the loop keeps
running without the link; its commands (:meth:`RigHost.command`) act on the
run's controller as the lab's act on an in-process run's.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from thermolab.agent.outbox import Outbox
from thermolab.agent.protocol import (
    LINK_LOST,
    OWNER_GONE,
    Heartbeat,
    LoopCommand,
    RunEnded,
    SampleOut,
    SetChannel,
    SetFan,
    SetGains,
    SetMode,
    StartRun,
)
from thermolab.errors import RigError, ThermoLabError
from thermolab.jsonsafe import json_safe
from thermolab.records import RUN_CHANNELS, ChannelSpec
from thermolab.rigs import Rig
from thermolab.runner import EventBus, Experiment, extra_channels
from thermolab.runner.control_request import build_control_loop
from thermolab.runner.pair import IOPair, check_pair
from thermolab.signals import parse_signal

__all__ = ["RigHost"]

log = logging.getLogger(__name__)


class _OutboxRecorder:
    """The runner's recorder into the outbox: one durable message per sample."""

    def __init__(self, host: RigHost, run_id: int) -> None:
        self._host = host
        self._run = run_id
        #: The run's channels (``Experiment`` checks them against its own).
        self.channels: tuple[ChannelSpec, ...] = RUN_CHANNELS
        #: The extra channels (a closed loop's), in the order ``write`` takes them.
        self.extra: tuple[str, ...] = ()

    def declare(self, extra: tuple[ChannelSpec, ...]) -> None:
        """The run records ``extra`` after the standard channels."""
        self.channels = (*RUN_CHANNELS, *extra)
        self.extra = tuple(c.name for c in extra)

    def open(self) -> None:
        """Nothing to prepare: the outbox is open."""

    def write(
        self,
        k: int,
        t: float,
        u: float,
        y: float,
        t_read: float,
        jitter: float,
        lateness: float,
        *extra: float,
    ) -> None:
        """Store the sample, every channel, in the outbox (its ``seq`` is given there)."""
        body = SampleOut(
            seq=1,
            run=self._run,
            k=k,
            t=t,
            u=u,
            y=y,
            t_read=t_read,
            jitter=jitter,
            lateness=lateness,
            extra=dict(zip(self.extra, extra, strict=True)) if self.extra else None,
        ).model_dump_json(exclude={"seq"})
        self._host.outbox.append("sample", body)
        self._host.note(u, y)

    def close(self) -> None:
        """Every sample is already committed."""


class RigHost:
    """One rig on its host, driven by the lab's commands and safe without them.

    Parameters
    ----------
    rig : Rig
        The open driver (the host owns it; :meth:`close` closes it).
    outbox : Outbox
    grace : float
        Seconds a run outlives a lost link before it is ENDed (the lab's
        ``Welcome`` may change it).
    on_outbox : callable, optional
        Called after something was added to the outbox (wakes the sender).
    """

    def __init__(
        self,
        rig: Rig,
        outbox: Outbox,
        *,
        grace: float = 30.0,
        on_outbox: Callable[[], None] | None = None,
    ) -> None:
        self.rig = rig
        self.outbox = outbox
        self.grace = grace
        #: Called after something was added to the outbox (the link sets it to wake its sender).
        self.on_outbox: Callable[[], None] = on_outbox or (lambda: None)
        self._lock = threading.RLock()
        self._run: Experiment | None = None
        self._run_id: int | None = None
        self._grace_timer: threading.Timer | None = None
        # Why the host ENDed the run going, if it did (told in its RunEnded).
        self._ended_for: str | None = None
        #: Whether the lab's machines answered the link's last tries (see :meth:`lab_answered`).
        self._lab_answers = False
        self._u: float | None = None
        self._y: float | None = None
        self.fault: str | None = None
        rig.power_off()

    # -- what the lab asks ----------------------------------------------------------------

    def start_run(self, command: StartRun) -> None:
        """START the lab's run ``command.run`` (refused while another run goes)."""
        with self._lock:
            if self._run is not None:
                raise ThermoLabError(f"run {self._run_id} is still going on this rig")
            info = self.rig.describe()
            pair = check_pair(info, *command.pair) if command.pair is not None else IOPair()
            limits = pair.limits(info, (info.input_min, info.input_max))
            signal = parse_signal(command.signal, limits) if command.signal is not None else None
            loop = None
            recorder = _OutboxRecorder(self, command.run)
            if command.control is not None:
                times = [k * command.dt for k in range(command.samples)]
                loop = build_control_loop(command.control, command.dt, times, info)
            recorder.declare(extra_channels(self.rig, info, loop))  # as the lab declared them
            experiment = Experiment(
                self.rig,
                command.dt,
                command.samples,
                signal=signal,
                set_point=command.input,
                recorder=recorder,
                events=EventBus(),
                controller=loop,
                pair=pair,
            )
            self._run, self._run_id = experiment, command.run
            experiment.start()
        threading.Thread(
            target=self._await_end,
            args=(experiment, command.run),
            daemon=True,
            name=f"agent-run-{command.run}",
        ).start()

    def refuse_run(self, run_id: int, message: str) -> None:
        """Tell the lab (durably) that run ``run_id`` could not start here."""
        body = RunEnded(seq=1, run=run_id, reason="error", message=message[:500], samples=0)
        self.outbox.append("run_ended", body.model_dump_json(exclude={"seq"}))
        self.on_outbox()

    def end_run(self, run_id: int) -> None:
        """END run ``run_id`` if it is the one going (the run stores its end itself)."""
        with self._lock:
            if self._run is not None and self._run_id == run_id:
                self._run.end()

    def set_input(self, u: float, run_id: int | None) -> None:
        """Hand ``u`` to the run going (``run_id``), or apply it to the powered idle rig."""
        with self._lock:
            if self._run is not None:
                if run_id == self._run_id:
                    self._run.set_input(u)
                return
            if run_id is None and self.rig.powered:
                self._guard(lambda: self._set_u(self.rig.apply(u)))

    def set_channel(self, name: str, level: float, run_id: int | None) -> None:
        """Hand a further input's level to the run going (``run_id``), or set it on the idle rig.

        Raises
        ------
        ThermoLabError
            As the run or the rig refuses it (the link logs it).
        """
        with self._lock:
            run = self._run
            if run is not None:
                if run_id == self._run_id:
                    run.set_further(name, level)
                return
            if run_id is None and self.rig.powered:
                self._guard(lambda: self.rig.set_channel(name, level))

    def command(self, command: LoopCommand) -> None:
        """Apply a closed-loop command to run ``command.run`` if it is the one going.

        Raises
        ------
        ThermoLabError
            As the run's :class:`~thermolab.runner.Experiment` refuses it (the link logs it).
        """
        with self._lock:
            run = self._run
            if run is None or command.run != self._run_id:
                raise ThermoLabError(f"run {command.run} is not going on this rig")
        if isinstance(command, SetMode):
            if command.auto:
                run.set_auto(command.setpoint)
            else:
                run.set_manual(command.u)
        elif isinstance(command, SetGains):
            run.set_gains(command.gains)
        elif isinstance(command, SetFan):
            run.set_fan(command.percent)
        elif isinstance(command, SetChannel):  # the link sends it to set_channel; kept whole
            self.set_channel(command.name, command.level, command.run)
        else:
            run.set_setpoint(command.setpoint)

    def power(self, on: bool) -> None:
        """Power the idle rig on (input at its safe value) or off."""
        with self._lock:
            if self._run is not None:
                return  # a run owns the rig; it powers it off when it ends
            if on and not self.rig.powered:
                self._guard(self.rig.power_on)
                self._guard(lambda: self._set_u(self.rig.apply(self.rig.describe().safe_input)))
            elif not on:
                self._guard(self.rig.power_off)
                self._u = None

    # -- the link ---------------------------------------------------------------------------

    def link_lost(self) -> None:
        """No lab: an idle rig goes off now, a run ENDs after the grace unless the link returns."""
        with self._lock:
            if self._run is None:
                self._guard(self.rig.power_off)
                self._u = None
                return
            if self._grace_timer is None:
                self._grace_timer = threading.Timer(self.grace, self._grace_over)
                self._grace_timer.daemon = True
                self._grace_timer.start()

    def lab_answered(self, answers: bool) -> None:
        """Whether the lab's machines answer the link's tries while it is down.

        ``True``: a worker answered but none took the link as the owner (closed
        it as a follower, refused the connection: nothing listens, or hung): the
        owner worker is gone. ``False``: no address answered at all (the
        network, or the lab's machine, is away). The run's END at the grace's
        end says which (:data:`~thermolab.agent.protocol.OWNER_GONE` or
        :data:`~thermolab.agent.protocol.LINK_LOST`), so that the lab stores the
        real cause.
        """
        # No lock: the link's event loop calls this, and the lock may be held by a rig's
        # command for a while (a serial read); one attribute's write is atomic.
        self._lab_answers = answers

    def link_back(self) -> None:
        """The lab is back: the run (if still going) goes on."""
        with self._lock:
            self._lab_answers = False
            if self._grace_timer is not None:
                self._grace_timer.cancel()
                self._grace_timer = None

    def heartbeat(self) -> Heartbeat:
        """The rig now (a fresh reading when no run samples it)."""
        with self._lock:
            if self._run is None and self.rig.powered:
                self._guard(lambda: self._read())
            loop = None if self._run is None else self._run.controller
            return Heartbeat(
                powered=self.rig.powered,
                u=self._u,
                y=self._y,
                fault=self.fault,
                run=self._run_id,
                pending=self.outbox.count(),
                loop=None if loop is None else json_safe(loop.to_dict()),
            )

    def note(self, u: float, y: float) -> None:
        """A sample was taken (by the run)."""
        self._u, self._y = u, y
        self.on_outbox()

    def close(self) -> None:
        """Abort any run and close the driver (actuator safe)."""
        with self._lock:
            run = self._run
        if run is not None:
            run.abort("the agent stopped")
            run.wait(30)
        with self._lock:
            self.rig.close()

    # -- internals ------------------------------------------------------------------------

    def _grace_over(self) -> None:
        with self._lock:
            self._grace_timer = None
            if self._run is not None:
                cause = OWNER_GONE if self._lab_answers else LINK_LOST
                log.warning(
                    "link lost for %.3g s: ENDing run %s (%s)", self.grace, self._run_id, cause
                )
                self._ended_for = f"{cause} for over {self.grace:g} s"
                self._run.end()

    def _await_end(self, experiment: Experiment, run_id: int) -> None:
        result = experiment.wait()
        with self._lock:
            self._run, self._run_id = None, None
            if self._grace_timer is not None:
                self._grace_timer.cancel()
                self._grace_timer = None
            reason = "error" if result is None else result.end_reason.value
            message = "" if result is None else (result.message or "")
            if reason == "ended" and self._ended_for is not None:
                message = self._ended_for  # the host's END: why (the lab stores it)
            self._ended_for = None
            samples = 0 if result is None else len(result.t)
            control = None if result is None else result.control
            body = RunEnded(
                seq=1,
                run=run_id,
                reason=reason,
                message=message[:500],
                samples=samples,
                control=None if control is None else json_safe(control),
            ).model_dump_json(exclude={"seq"})
            self.outbox.append("run_ended", body)
            if reason == "rig_fault":
                self.fault = message or "rig fault"
            if not self.rig.powered:  # the run left the rig off (actuator safe)
                self._u = None
        self.on_outbox()

    def _set_u(self, u: float) -> None:
        self._u = u

    def _read(self) -> None:
        self._y = self.rig.read().value

    def _guard(self, action: Callable[[], object]) -> None:
        try:
            action()
        except RigError as exc:
            self.fault = str(exc)
            log.warning("rig fault: %s", exc)
            try:
                self.rig.power_off()
            except RigError:
                log.exception("cannot power the rig off after a fault")
