"""Rigs: one interface for the digital twin and every hardware driver.

See :mod:`thermolab.rigs.contract` for the interface (:class:`Rig`,
:class:`RigInfo`, :class:`Reading`, :class:`RigState`),
:mod:`thermolab.rigs.base` for :class:`BaseRig` (the state machine and safe
state every rig shares) and :mod:`thermolab.rigs.clock` for the clocks every
rig and the runner share.
The implementations are the digital twin (:mod:`thermolab.rigs.twin`) and the
TCLab driver (:mod:`thermolab.rigs.tclab`; finding a kit's port:
:mod:`thermolab.rigs.tclab_port`; heaters off when the process ends:
:mod:`thermolab.rigs.tclab_exit`); :class:`RigSpec` parses the one-line
specification that names a rig (``sim``, ``sim:PRESET``, ``tclab``,
``tclab:PORT``) and tells what it is without opening it (units, ranges, safe
input, defaults: :mod:`thermolab.rigs.spec`); :func:`open_rig` opens it. The TCLab firmware emulator
(:mod:`thermolab.rigs.tclab_emulator`, POSIX only: it needs a pseudo-terminal)
is imported from its module.
"""

from thermolab.errors import RigError, RigFaultError, RigStateError, RigTimeoutError
from thermolab.rigs._factory import RIG_SPECS, open_rig
from thermolab.rigs.base import BaseRig
from thermolab.rigs.clock import (
    Clock,
    RateClock,
    RealClock,
    ScaledClock,
    VirtualClock,
    make_clock,
)
from thermolab.rigs.contract import (
    PRIMARY_PAIR,
    InputChannel,
    OutputChannel,
    Reading,
    Rig,
    RigInfo,
    RigState,
)
from thermolab.rigs.kit_twin import KitTwinRig
from thermolab.rigs.spec import RIG_KINDS, RigKind, RigSpec
from thermolab.rigs.tclab import TCLabRig, tclab_info
from thermolab.rigs.tclab_port import TCLabVersion, find_tclab
from thermolab.rigs.twin import PRESETS, TwinParams, TwinRig, twin_info, twin_params, twin_preset

__all__ = [
    "PRESETS",
    "PRIMARY_PAIR",
    "RIG_KINDS",
    "RIG_SPECS",
    "BaseRig",
    "Clock",
    "InputChannel",
    "KitTwinRig",
    "OutputChannel",
    "RateClock",
    "Reading",
    "RealClock",
    "Rig",
    "RigError",
    "RigFaultError",
    "RigInfo",
    "RigKind",
    "RigSpec",
    "RigState",
    "RigStateError",
    "RigTimeoutError",
    "ScaledClock",
    "TCLabRig",
    "TCLabVersion",
    "TwinParams",
    "TwinRig",
    "VirtualClock",
    "find_tclab",
    "make_clock",
    "open_rig",
    "tclab_info",
    "twin_info",
    "twin_params",
    "twin_preset",
]
