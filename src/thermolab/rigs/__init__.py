"""Rigs: one interface for the digital twin and every hardware driver.

See :mod:`thermolab.rigs.base` for the interface (:class:`Rig`,
:class:`BaseRig`, :class:`RigInfo`, :class:`Reading`, :class:`RigState`) and
:mod:`thermolab.rigs.clock` for the clocks every rig and the runner share.
"""

from thermolab.errors import RigError, RigFaultError, RigStateError, RigTimeoutError
from thermolab.rigs.base import BaseRig, Reading, Rig, RigInfo, RigState
from thermolab.rigs.clock import Clock, RealClock, ScaledClock, VirtualClock, make_clock

__all__ = [
    "BaseRig",
    "Clock",
    "Reading",
    "RealClock",
    "Rig",
    "RigError",
    "RigFaultError",
    "RigInfo",
    "RigState",
    "RigStateError",
    "RigTimeoutError",
    "ScaledClock",
    "VirtualClock",
    "make_clock",
]
