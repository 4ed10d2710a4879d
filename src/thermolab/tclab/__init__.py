"""The ``tclab`` package's interface on a ThermoLab rig: change only the import.

A course notebook written for the TCLab kit (``from tclab import TCLab,
clock, Historian``) runs against a lab rig with ``from thermolab.tclab import
TCLab, clock, Historian`` — or against the lab's twin at its speed-up with
``TCLab = setup(connected=False)``. The lab, token and rig come from
arguments or ``THERMOLAB_URL``, ``THERMOLAB_TOKEN``, ``THERMOLAB_RIG``.
Written after the ``tclab`` package's documented API (names and meaning), not
its code; see :mod:`thermolab.tclab.remote` for what happens on the way out.
"""

from __future__ import annotations

from thermolab.tclab.historian import Historian
from thermolab.tclab.labtime import LabTime, clock, labtime
from thermolab.tclab.plotter import Plotter
from thermolab.tclab.remote import ENV_RIG, SecondHeaterError, TCLab

__all__ = [
    "ENV_RIG",
    "Historian",
    "LabTime",
    "Plotter",
    "SecondHeaterError",
    "TCLab",
    "clock",
    "labtime",
    "setup",
]


def setup(connected: bool = True, speedup: float = 1) -> type[TCLab]:
    """Return the ``TCLab`` class to use, as the ``tclab`` package's ``setup`` does.

    Parameters
    ----------
    connected : bool
        ``True``: a lab rig (a kit, if the lab has one); ``False``: the lab's
        simulated rig (its twin), in place of the kit's offline model.
    speedup : float
        Only with ``connected=False``. The twin runs at the lab's speed-up,
        which the lab decides (``thermolab serve --speedup``); ``clock`` follows
        it, and a different value asked for is reported, not applied.

    Raises
    ------
    ValueError
        For a speed-up with ``connected=True`` (a real rig runs in real time).
    """
    if connected and speedup != 1:
        raise ValueError("setup(connected=True) runs a real rig in real time: speedup must be 1")
    if not speedup > 0:
        raise ValueError(f"speedup must be positive; got {speedup!r}")
    asked = float(speedup)

    class RemoteTCLab(TCLab):
        _simulated = not connected

        def __init__(self, *args: object, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)  # type: ignore[arg-type]
            if not connected and asked != 1 and asked != self.lab.speedup:
                print(
                    f"note: the lab runs its twin at {self.lab.speedup:g}x, not {asked:g}x; "
                    "clock() follows the lab"
                )

    RemoteTCLab.__name__ = RemoteTCLab.__qualname__ = "TCLab"
    return RemoteTCLab
