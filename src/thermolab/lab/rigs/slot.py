"""One rig as the lab holds it: its state, its pace and its power rules.

:class:`RigSlot` owns what :class:`~thermolab.lab.rigs.devices.DeviceHub`
knows of one rig (its driver, power, controller, latest reading, fault) and
the steps that change it under the rig's lock: a twin's pace, the hand-over
between turns, a rig host's rest, and the power machine of a reconcile. The
hub takes the lock, picks the slot, and calls these; the slot never locks.
"""

from __future__ import annotations

import threading
from datetime import datetime

from thermolab.errors import RigError, ThermoLabError
from thermolab.lab.config import RigConfig
from thermolab.lab.config.rig_kinds import published_defaults
from thermolab.lab.db.models import PowerState
from thermolab.rigs import RateClock, Reading, Rig

__all__ = ["RigSlot", "level_of"]


class RigSlot:
    """One rig as the hub holds it."""

    def __init__(self, config: RigConfig) -> None:
        self.config = config
        self.lock = threading.RLock()
        self.driver: Rig | None = None
        self.published = published_defaults(config)
        self.powered = False
        self.controller_session: int | None = None
        self.output: float | None = None
        self.output_at: datetime | None = None
        self.fault: str | None = None
        self.claimed = False
        self.input: float | None = None
        self.host_speedup: float | None = None  # a rig host's, as its Hello said
        # A rig host's further actuators (a fan), as its run's samples and its rests
        # tell them (None: not known yet); an in-process driver is read instead.
        self.host_levels: dict[str, float | None] = dict.fromkeys(config.rig_spec.actuators)
        # The further outputs (a kit's T2) the rig declares, and the latest reading's.
        self.output_names = tuple(config.rig_spec.describe().outputs)
        self.further_outputs: dict[str, float] = {}
        # A controller's own speed-up of a twin for their turn: (control session, speed-up).
        self.turn_pace: tuple[int, float] | None = None

    def fail(self, exc: RigError) -> None:
        """The device failed: its error is the rig's fault, and the rig is off, uncontrolled."""
        self.fault = str(exc)
        self.powered = False
        self.controller_session = None

    def take(self, reading: Reading) -> float:
        """Keep a reading the hub took: ``y`` (returned), and the further outputs it carries."""
        self.output = reading.value
        self.further_outputs = dict(reading.further)
        return reading.value

    def speedup_in_force(self, rig: RigConfig) -> float:
        """The twin's pace now: the turn's own (capped by the teacher's), else the teacher's."""
        if self.turn_pace is None:
            return rig.twin_speedup
        return min(self.turn_pace[1], rig.twin_speedup)

    def pace(self, rig: RigConfig) -> None:
        """Set a twin's clock the lab runs to the speed-up in force (others keep their own)."""
        clock = None if self.driver is None else self.driver.clock
        if isinstance(clock, RateClock) and rig.lab_twin:
            clock.set_rate(self.speedup_in_force(rig))

    def apply(self, u: float) -> float | None:
        """Apply ``u`` to the driver, if any; return the value applied."""
        if self.driver is None:
            return None
        self.input = self.driver.apply(u)
        return self.input

    def host_at_rest(self) -> None:
        """A rig host's rig was powered off: by the rig contract, at its declared defaults."""
        for name, spec in self.config.rig_spec.actuators.items():
            self.host_levels[name] = spec.default

    def hand_over(self) -> None:
        """The one hand-over of a powered rig between turns: the rig's own safe state.

        Powering the driver off puts every actuator its kind declares at its
        declared default (the input at its safe value, a twin's fan off: the
        :mod:`thermolab.rigs.contract` rule), so nothing a turn set reaches the
        next one, whatever the rig has; then it is powered again at its safe
        input. A rig host's rig (no driver here) is handed over by its host.
        """
        if self.driver is not None:
            self.driver.power_off()
            self.driver.power_on()
        self.input = None
        self.apply(self.published.safe_input)
        if self.driver is None and self.config.agent:
            self.input = self.published.safe_input  # what the host is told to hold
            self.host_at_rest()

    def follow_power(
        self, power: PowerState, controller_session: int | None, cooldown_input: float | None
    ) -> bool:
        """Power the rig as the database says; return whether the rig was handed over.

        Powers it on or off; on a change of controller (or none) hands it over
        (:meth:`hand_over`); while cooling holds ``cooldown_input``, within the
        rig's range. Raises the device's :class:`~thermolab.errors.RigError`.
        """
        driver = self.driver
        if driver is not None:
            # The device's own state wins: a run powers the rig off when it ends.
            self.powered = driver.powered
        if power is PowerState.OFF:
            if driver is not None and self.powered:
                driver.power_off()
            self.powered = False
            self.controller_session = None
            self.input = None
            if driver is None and self.config.agent:
                self.host_at_rest()  # told Power(off): its rig's safe state
            return False
        handed_over = False
        if not self.powered:
            if driver is not None:
                driver.power_on()
            self.powered = True
            self.controller_session = None
            self.apply(self.published.safe_input)
        if power is PowerState.COOLING:
            handed_over = self.controller_session is not None
            if handed_over:
                self.hand_over()
            self.controller_session = None
            target = self.published.safe_input if cooldown_input is None else cooldown_input
            self.apply(min(max(target, self.published.input_min), self.published.input_max))
        elif controller_session != self.controller_session:
            handed_over = True
            self.controller_session = controller_session
            self.hand_over()
        return handed_over


def level_of(driver: object, name: str) -> float | None:
    """The driver's further input ``name`` now; ``None`` with no driver or one that cannot say."""
    level = getattr(driver, "level", None)
    if not callable(level):
        return None
    try:
        return float(level(name))
    except ThermoLabError:  # a stand-in driver that does not declare it
        return None
