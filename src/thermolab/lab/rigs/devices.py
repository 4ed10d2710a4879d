"""The lab's hands on its rigs: power, safe state, inputs, readings.

The database says what a rig *should* be doing (powered or not, cooling,
who controls it); :class:`DeviceHub` makes the rig do it. After every change of
access state the lab calls :meth:`DeviceHub.reconcile` with the rig's current
state read back from the database, under a per-rig lock, so the rig always
ends up matching the latest committed state whatever order requests finish
in. Slow device I/O (a TCLab resets for about 2 s when its port opens) never
happens while a database lock is held.

A rig's driver is opened by an *opener* (``RigConfig -> Rig``, any object of
the :class:`thermolab.rigs.Rig` interface). Without one, the hub still
publishes the rig's input range from its kind and configuration, and records
that inputs were not applied to a device.

A twin the lab runs has its own :class:`~thermolab.rigs.RateClock`; the hub
sets its rate to the teacher's ``twin_speedup`` when a run STARTs
(:meth:`DeviceHub.claim`), when the setting is saved while no run is going
(:meth:`DeviceHub.follow_settings`) and when a run ends, so a run keeps the
pace it started with and simulated time never jumps.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime

from thermolab.errors import ConflictError, RigError, SpeedupRefusedError, ThermoLabError
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig, RigConfig
from thermolab.lab.config.rig_kinds import (
    ActuatorLevel,
    PublishedRig,
    narrow_range,
    published_defaults,
)
from thermolab.lab.db.models import PowerState
from thermolab.lab.rigs.opener import RigOpener
from thermolab.lab.rigs.slot import RigSlot, level_of
from thermolab.rigs import RateClock, Rig

__all__ = [
    "DesiredState",
    "DeviceHub",
    "PublishedRig",
    "published_defaults",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class DesiredState:
    """What the database says a rig should be doing.

    Attributes
    ----------
    power : PowerState
    controller_session : int or None
        The active control session, if any; a change puts the input back to safe.
    """

    power: PowerState
    controller_session: int | None


class DeviceHub:
    """Live rigs of the lab, kept in line with the database.

    Parameters
    ----------
    config : LabConfig
    opener : RigOpener or None
        Opens a rig's driver; ``None`` runs the lab without devices (inputs are
        validated and recorded but reach no rig).
    clock : LabClock, optional
        Dates the readings a run hands in (:meth:`note_reading`).

    Examples
    --------
    >>> from pathlib import Path
    >>> from thermolab.lab.config import default_config
    >>> hub = DeviceHub(default_config(Path("/tmp/lab")), opener=None)
    >>> hub.published("twin").input_max
    10.0
    >>> hub.apply("twin", 2.5, controller_session=1) is None  # no device attached
    True
    """

    def __init__(
        self, config: LabConfig, opener: RigOpener | None, clock: LabClock | None = None
    ) -> None:
        self._opener = opener
        self._clock = clock
        self._config = config
        self._slots = {rig.id: RigSlot(rig) for rig in config.rigs}

    def open_all(self) -> dict[str, str]:
        """Open every rig's driver and put it in its safe state.

        Returns
        -------
        dict
            Rig id -> fault message, for the rigs that could not be opened.
        """
        faults: dict[str, str] = {}
        for rig_id, slot in self._slots.items():
            fault = self._open(slot)
            if fault is not None:
                faults[rig_id] = fault
        return faults

    def _open(self, slot: RigSlot) -> str | None:
        with slot.lock:
            if self._opener is None or slot.driver is not None or slot.config.agent:
                return None  # a remote rig's driver is on its host (thermolab.lab.agents)
            try:
                driver = self._opener(slot.config)
                driver.power_off()
                base = PublishedRig.of(driver.describe(), live=True)
                slot.published = narrow_range(base, slot.config)
                slot.driver = driver
                slot.fault = None
                return None
            except (ThermoLabError, OSError) as exc:
                slot.fault = f"cannot open {slot.config.spec!r}: {exc}"
                log.warning("rig %s: %s", slot.config.id, slot.fault)
                return slot.fault

    def claim(self, rig_id: str) -> None:
        """A run takes the device: the hub leaves it alone until :meth:`release`.

        A twin's clock takes the speed-up in force, which the run keeps to its end.
        """
        slot = self._slots[rig_id]
        with slot.lock:
            slot.pace(self._config.rig(rig_id))
            slot.claimed = True

    def release(self, rig_id: str, *, left_off: bool = False) -> None:
        """The run is over: the hub looks after the device again (call :meth:`reconcile`).

        A twin's clock takes the speed-up in force (saved during the run, perhaps).
        ``left_off``: the run powered a device the hub does not hold off (a rig
        host's), so the hub powers it on again at its safe input, never at the
        run's last input (a driver's own state tells this in-process).
        """
        slot = self._slots[rig_id]
        with slot.lock:
            slot.claimed = False
            slot.controller_session = None
            driver = slot.driver
            if driver is not None and not driver.powered:
                # The run powered the device off as it ended: the hub says so from now on,
                # not the run's last input until the next reconcile (a reader between the
                # two saw an idle rig "powered at 6 V" that was off).
                slot.powered, slot.input = False, None
            if left_off:
                slot.powered, slot.input = False, None
                slot.host_at_rest()  # its runner powered it off: the rig's safe state
            slot.pace(self._config.rig(rig_id))

    def follow_settings(self, rig: RigConfig) -> None:
        """A rig's teacher settings were put in force: a twin with no run takes its speed-up.

        A run going keeps its pace; :meth:`release` applies the new one after it.
        """
        slot = self._slots.get(rig.id)
        if slot is None:
            return
        with slot.lock:
            if not slot.claimed:
                slot.pace(rig)

    def clock_rate(self, rig_id: str) -> float | None:
        """The rate of the rig's clock if the hub sets it (a twin the lab runs), else ``None``."""
        driver = self._slots[rig_id].driver
        clock = None if driver is None else driver.clock
        return clock.rate if isinstance(clock, RateClock) else None

    def pace_turn(self, rig_id: str, speedup: float, *, controller_session: int) -> float:
        """Run a twin at ``speedup`` for the controller's turn; return the speed-up in force.

        Allowed: a twin the lab runs, from real time (1) up to its teacher's
        ``twin_speedup``, while no run is going (a run keeps its pace). The
        turn's speed-up ends with the turn (:meth:`reconcile`), and a teacher's
        lower ``twin_speedup`` caps it.

        Raises
        ------
        SpeedupRefusedError
            For hardware or a rig host's twin, or a speed-up outside what the twin allows.
        ConflictError
            While a run is going, or when ``controller_session`` is no longer the rig's turn.
        """
        slot = self._slots[rig_id]
        rig = self._config.rig(rig_id)
        if not rig.lab_twin or self.clock_rate(rig_id) is None:
            raise SpeedupRefusedError(
                f"rig {rig_id!r} ({rig.spec}) runs at its own pace, not the lab's: it is "
                "hardware or a twin on a rig host, so only 1x (real time for hardware) is "
                f"allowed; {speedup:g}x was asked"
            )
        if not (1.0 <= speedup <= rig.twin_speedup):
            raise SpeedupRefusedError(
                f"rig {rig_id!r} (a twin) allows speed-ups from 1x to {rig.twin_speedup:g}x "
                f"(its teacher's twin_speedup); {speedup:g}x was asked"
            )
        with slot.lock:
            if slot.claimed:
                raise ConflictError(
                    f"a run is going on rig {rig_id!r}: it keeps the pace it started with; "
                    "change the speed-up before its START",
                    case="pace_fixed_during_run",
                )
            slot.turn_pace = (controller_session, float(speedup))
            slot.pace(rig)
        return speedup

    def note_sample(
        self,
        rig_id: str,
        u: float,
        y: float,
        *,
        of_run: bool = False,
        channels: Mapping[str, float | None] | None = None,
    ) -> None:
        """Record a sample taken by someone else (a run samples the rig; a rig host reports).

        ``of_run``: a run's sample, ignored once the run has let the rig go
        (:meth:`release`). Its recorder stores samples in batches and may hand
        the last ones in after the end; the input they carry is history, not
        what the rig now has. ``channels``: the sample's further channels; a
        rig host's further actuators (a fan) are known from them.
        """
        slot = self._slots[rig_id]
        with slot.lock:
            if of_run and not slot.claimed:
                return
            for name, level in (channels or {}).items():
                if name in slot.host_levels and level is not None:
                    slot.host_levels[name] = level
                elif level is not None and name in slot.output_names:
                    slot.further_outputs[name] = level
            slot.input = u
            slot.output = y
            slot.output_at = self._clock.now() if self._clock is not None else slot.output_at

    def driver(self, rig_id: str) -> Rig | None:
        """Return the rig's open driver, if any (the runner samples it during a run)."""
        return self._slots[rig_id].driver

    def published(self, rig_id: str) -> PublishedRig:
        """Return what rig ``rig_id`` accepts and its pace (KeyError for an unknown rig).

        The pace (``speedup``) is read now: a twin's teacher setting may change,
        and a rig host says its own when it dials in (:meth:`host_said`).
        """
        slot = self._slots[rig_id]
        rig = self._config.rig(rig_id)
        speedup = slot.host_speedup if rig.agent else rig.speedup
        if rig.lab_twin and slot.turn_pace is not None:
            speedup = slot.speedup_in_force(rig)
        levels = self.actuators(rig_id)
        actuators = tuple(
            ActuatorLevel(name, spec.unit, spec.default, levels[name])
            for name, spec in rig.rig_spec.actuators.items()
        )
        return dataclasses.replace(slot.published, speedup=speedup, actuators=actuators)

    def host_said(self, rig_id: str, speedup: float) -> None:
        """A rig host dialled in and said how fast its rig runs (``Hello.speedup``)."""
        self._slots[rig_id].host_speedup = speedup

    def input_range(self, rig_id: str) -> tuple[float, float]:
        """The rig's published input range (KeyError for an unknown rig)."""
        published = self._slots[rig_id].published
        return (published.input_min, published.input_max)

    def reading(self, rig_id: str) -> tuple[float, datetime] | None:
        """Return the latest reading of the rig's output and when it was taken, if any."""
        slot = self._slots[rig_id]
        if slot.output is None or slot.output_at is None:
            return None
        return (slot.output, slot.output_at)

    def read_now(self, rig_id: str) -> tuple[float, datetime] | None:
        """Read the rig's output now (a script's ``T1``); ``None`` if it cannot be read.

        Not read while a run holds the device (the run samples it: its latest
        sample is :meth:`reading`), nor when the rig is off, faulted or absent.
        """
        slot = self._slots[rig_id]
        with slot.lock:
            driver = slot.driver
            if driver is None or slot.claimed or slot.fault is not None or not driver.powered:
                return None
            try:
                value = slot.take(driver.read())
            except RigError as exc:
                slot.fail(exc)
                return None
            slot.output_at = self._clock.now() if self._clock is not None else slot.output_at
            return None if slot.output_at is None else (value, slot.output_at)

    def fault(self, rig_id: str) -> str | None:
        """Return the rig's pending fault, if any."""
        slot = self._slots[rig_id]
        return slot.fault

    def clear_fault(self, rig_id: str) -> None:
        """Forget a fault (a teacher cleared it).

        The driver is asked to clear its own (it refuses while the cause
        persists); a rig that could not be opened is opened again.
        """
        slot = self._slots[rig_id]
        with slot.lock:
            slot.fault = None
            if slot.driver is None:
                self._open(slot)
                return
            try:
                slot.driver.clear_fault()
            except RigError as exc:
                slot.fault = str(exc)

    @contextmanager
    def locked(self, rig_id: str) -> Iterator[None]:
        """Hold the rig's lock (to read the database state and reconcile as one step)."""
        with self._slots[rig_id].lock:
            yield

    def reconcile(self, rig_id: str, desired: DesiredState, cooldown_input: float | None) -> bool:
        """Make the rig match ``desired``; return whether the rig was handed over.

        Powers the rig on or off; on a change of controller (or none) hands the
        rig over (:meth:`~thermolab.lab.rigs.slot.RigSlot.hand_over`: every
        actuator at its declared default); while cooling holds
        ``cooldown_input`` (:meth:`~thermolab.lab.rigs.slot.RigSlot.follow_power`).
        Errors of the device become the rig's fault (see :meth:`fault`). A rig
        host's rig is handed over by its host when the lab says so
        (``AgentHub.sync_power(hand_over=True)``).
        """
        slot = self._slots[rig_id]
        with slot.lock:
            if slot.claimed:
                return False
            if slot.turn_pace is not None and slot.turn_pace[0] != desired.controller_session:
                slot.turn_pace = None  # the turn that chose it is over: the teacher's pace again
                slot.pace(self._config.rig(rig_id))
            try:
                return slot.follow_power(desired.power, desired.controller_session, cooldown_input)
            except RigError as exc:
                slot.fail(exc)
                log.warning("rig %s: %s", rig_id, exc)
                return False

    def apply(self, rig_id: str, u: float, *, controller_session: int) -> float | None:
        """Apply a controller's input; return the value applied, or ``None`` if not applied.

        Not applied when no device is attached, the rig is not powered, or the
        control session is no longer the rig's (it ended meanwhile).
        """
        slot = self._slots[rig_id]
        with slot.lock:
            if slot.driver is None or slot.claimed or not slot.driver.powered:
                return None
            if slot.controller_session != controller_session:
                return None
            try:
                return slot.apply(u)
            except RigError as exc:
                slot.fail(exc)
                return None

    def set_channel(
        self, rig_id: str, name: str, level: float, *, controller_session: int
    ) -> float | None:
        """Set a controller's further input (a kit's heater 2); return the level set, or ``None``.

        As :meth:`apply`: not set when no device is attached, a run holds it,
        the rig is not powered, or the control session is no longer the rig's.
        """
        slot = self._slots[rig_id]
        with slot.lock:
            driver = slot.driver
            if driver is None or slot.claimed or not driver.powered:
                return None
            if slot.controller_session != controller_session:
                return None
            try:
                return float(driver.set_channel(name, level))
            except RigError as exc:
                slot.fail(exc)
                return None

    def channels(self, rig_id: str) -> dict[str, float | None]:
        """The rig's further channels now: its outputs as last read, its inputs' levels.

        Empty for a rig that declares none; ``None`` for one not known yet.
        """
        slot = self._slots[rig_id]
        read = {name: slot.further_outputs.get(name) for name in slot.output_names}
        return {**read, **self.actuators(rig_id)}

    def poll(self, now: datetime) -> None:
        """Take a reading of every attached rig (keeps :meth:`output` fresh)."""
        for slot in self._slots.values():
            with slot.lock:
                if slot.driver is None or slot.fault is not None or slot.claimed:
                    continue
                try:
                    slot.take(slot.driver.read())
                    slot.output_at = now
                except RigError as exc:
                    slot.fail(exc)

    def close(self) -> None:
        """Close every driver, leaving each actuator at its safe value."""
        for slot in self._slots.values():
            with slot.lock:
                if slot.driver is not None:
                    slot.driver.close()
                    slot.driver = None
                slot.powered = False

    def powered(self, rig_id: str) -> bool:
        """Whether the hub holds the rig powered (not during a run, which owns the rig)."""
        slot = self._slots[rig_id]
        return slot.powered and not slot.claimed

    def applied(self, rig_id: str) -> float | None:
        """Return the input the hub last applied to the rig, if any."""
        return self._slots[rig_id].input

    def actuators(self, rig_id: str) -> dict[str, float | None]:
        """Every further actuator the rig's kind declares, at its level now (``None``: unknown).

        Read from the open driver (:meth:`~thermolab.rigs.Rig.level`, for each
        :class:`~thermolab.rigs.InputChannel` its spec declares); a rig host's, from its run's
        samples and, once its rig was powered off (a run's end, a hand-over),
        its declared default (``None`` until then).
        """
        slot = self._slots[rig_id]
        driver = slot.driver  # one attribute read, no lock: views read it in a transaction
        if driver is None and slot.config.agent:
            return dict(slot.host_levels)
        return {name: level_of(driver, name) for name in slot.config.rig_spec.actuators}
