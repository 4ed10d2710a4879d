"""The ``tclab`` package's interface on a ThermoLab rig: change only the import.

A course notebook written for the TCLab kit (``from tclab import TCLab,
clock, Historian``) runs against a lab rig with ``from thermolab.tclab import
TCLab, clock, Historian``; with ``setup(connected=False, speedup=...)`` against
the lab's twin (when a lab is named) or the offline :class:`TCLabModel`. The
lab, token and rig come from arguments or ``THERMOLAB_URL``,
``THERMOLAB_TOKEN``, ``THERMOLAB_RIG``. Every public name of ``tclab`` 1.0.x
is here with its signature, defaults, units and meaning — written after the
package's documented API and source (names and meaning), not copied from
them. Where a lab rig cannot do what the kit does (a second heater on a
one-heater rig, a heater limit above the kit's), a clear error says so.
"""

from __future__ import annotations

from thermolab.tclab.diagnose import diagnose
from thermolab.tclab.experiment import Experiment, runexperiment
from thermolab.tclab.historian import Historian, NoDatabaseError
from thermolab.tclab.kit_errors import (
    AlreadyConnectedError,
    NotAKitError,
    NotOnThisRigError,
    PortError,
    SecondHeaterError,
)
from thermolab.tclab.labtime import LabTime, LabTimeStoppedError, clock, labtime, setnow
from thermolab.tclab.model import TCLabModel
from thermolab.tclab.plotter import Plotter
from thermolab.tclab.remote import TCLab
from thermolab.tclab.rig_choice import ENV_RIG
from thermolab.tclab.switch import SpeedupRefusedError, setup
from thermolab.tclab.tagdb import TagDB

__version__ = "1.0.0"
"""The ``tclab`` version whose interface this gives (ThermoLab's: ``thermolab.__version__``)."""

__all__ = [
    "ENV_RIG",
    "AlreadyConnectedError",
    "Experiment",
    "Historian",
    "LabTime",
    "LabTimeStoppedError",
    "NoDatabaseError",
    "NotAKitError",
    "NotOnThisRigError",
    "Plotter",
    "PortError",
    "SecondHeaterError",
    "SpeedupRefusedError",
    "TCLab",
    "TCLabModel",
    "TagDB",
    "__version__",
    "clock",
    "diagnose",
    "labtime",
    "runexperiment",
    "setnow",
    "setup",
]
