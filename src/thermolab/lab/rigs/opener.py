"""How the lab opens a configured rig's driver: :func:`device_opener`.

Kept apart from the hub (:mod:`.devices`) that holds the opened drivers: the
lab, a fleet worker and the tests choose an opener (tests inject twins on
clocks of their own) without the hub's machinery.
"""

from __future__ import annotations

from collections.abc import Callable

from thermolab.lab.config import RigConfig
from thermolab.rigs import RateClock, RealClock, Rig

__all__ = ["RigOpener", "device_opener"]

RigOpener = Callable[[RigConfig], Rig]
"""Opens the driver of a configured rig (the digital twin, a TCLab on its port)."""


def device_opener() -> RigOpener:
    """Return the opener of real rigs: :meth:`thermolab.rigs.RigSpec.open` on the rig's spec.

    Each twin gets a clock of its own whose rate the hub changes (a
    :class:`~thermolab.rigs.RateClock` at the rig's ``twin_speedup``);
    hardware always runs in real time.

    Examples
    --------
    >>> opener = device_opener()
    >>> with opener(RigConfig("a", "A", "sim:tclab", twin_speedup=20.0)) as rig:
    ...     rig.describe().input_unit, rig.clock.rate
    ('%', 20.0)
    """

    def open_configured(rig: RigConfig) -> Rig:
        spec = rig.rig_spec
        return spec.open(clock=RateClock(rig.twin_speedup) if spec.simulated else RealClock())

    return open_configured
