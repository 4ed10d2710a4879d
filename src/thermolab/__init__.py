"""ThermoLab: a remote laboratory for identifying a temperature control system.

The package is layered (see ``docs/architecture.md``):

* numerics — :mod:`thermolab.ident`, :mod:`thermolab.signals`,
  :mod:`thermolab.simulation`, :mod:`thermolab.reproduction`;
* rigs and the experiment runner — :mod:`thermolab.rigs`, :mod:`thermolab.runner`;
* the lab service — :mod:`thermolab.lab`;
* the browser interface — :mod:`thermolab.web`;
* the command line — :mod:`thermolab.cli`.

Each layer imports only from the layers below it.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
