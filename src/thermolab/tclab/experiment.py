"""``Experiment`` and ``runexperiment``: a kit, a historian, a plotter and a clock in one ``with``.

Names, arguments and defaults are the ``tclab`` package's. ``connected=True``
drives a lab rig (:class:`~thermolab.tclab.TCLab`); ``connected=False`` the
lab's twin when a lab is named (``$THERMOLAB_URL``), else the offline
:class:`~thermolab.tclab.TCLabModel` — the same choice as
:func:`~thermolab.tclab.setup`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

from thermolab.tclab.historian import Historian
from thermolab.tclab.kit_errors import NotOnThisRigError
from thermolab.tclab.labtime import clock, labtime
from thermolab.tclab.model import TCLabModel
from thermolab.tclab.plotter import Plotter
from thermolab.tclab.remote import TCLab
from thermolab.tclab.switch import uses_lab_twin

__all__ = ["Experiment", "runexperiment"]


class Experiment:
    """Connect a kit, log it and plot it for ``time`` lab seconds (a context manager).

    Parameters
    ----------
    connected : bool
        A lab rig (``True``), or a simulated kit (``False``; see the module).
    plot : bool
        Draw a :class:`~thermolab.tclab.Plotter` as the experiment runs.
    twindow : float
        Seconds the plotter shows.
    time : int
        Lab seconds :meth:`clock` runs, one step a second.
    dbfile : str
        The historian's database (default: in memory).
    speedup : float
        Lab time's speed-up with ``connected=False`` (a lab's twin runs at its own).
    synced : bool
        ``False``: the offline model moves one second per step as fast as the
        computer goes (no clock); a lab rig cannot (refused).
    tol : float
        The clock's tolerance, lab seconds.

    Attributes
    ----------
    lab, historian, plotter
        Made on entering the ``with`` block (``plotter`` only with ``plot``).

    Raises
    ------
    ValueError
        For a speed-up or ``synced=False`` with ``connected=True``.
    """

    def __init__(
        self,
        connected: bool = True,
        plot: bool = True,
        twindow: float = 200,
        time: int = 500,
        dbfile: str = ":memory:",
        speedup: float = 1,
        synced: bool = True,
        tol: float = 0.5,
    ) -> None:
        if (speedup != 1 or not synced) and connected:
            raise ValueError(
                "Experiment(connected=True) runs a real rig in real time: speedup must be 1 "
                "and synced True"
            )
        self.connected = connected
        self.plot = plot
        self.twindow = twindow
        self.time = time
        self.dbfile = dbfile
        self.speedup = speedup
        self.synced = synced
        self.tol = tol
        self._twin = not connected and uses_lab_twin()
        if self._twin and not synced:
            raise NotOnThisRigError(
                "Experiment(connected=False, synced=False) runs the kit as fast as the computer "
                "goes; the lab's twin runs on the lab's clock. Unset $THERMOLAB_URL to use the "
                "offline TCLabModel, or keep synced=True"
            )
        if synced and not self._twin:
            labtime.set_rate(speedup)
        self.lab: TCLab | TCLabModel | None = None
        self.historian: Historian | None = None
        self.plotter: Plotter | None = None

    def __enter__(self) -> Experiment:
        if self.connected or self._twin:
            kind = type("TCLab", (TCLab,), {"_simulated": not self.connected})
            self.lab = kind()
        else:
            self.lab = TCLabModel(synced=self.synced)
        self.historian = Historian(self.lab.sources, dbfile=self.dbfile)
        if self.plot:
            self.plotter = Plotter(self.historian, twindow=self.twindow)
        return self

    def __exit__(self, exc_type: object, exc_value: object, traceback: object) -> None:
        if self.lab is not None:
            self.lab.close()
        if self.historian is not None:
            self.historian.close()

    def clock(self) -> Iterator[float]:
        """Yield each second of the experiment, then log (and plot) the kit at it."""
        if self.lab is None or self.historian is None:
            raise RuntimeError("Experiment.clock() runs inside the with-block")
        times: Iterator[float] = (
            clock(self.time, tol=self.tol) if self.synced else iter(map(float, range(self.time)))
        )
        for t in times:
            yield t
            if self.plotter is not None:
                self.plotter.update(t)
            else:
                self.historian.update(t)
            if not self.synced and isinstance(self.lab, TCLabModel):
                self.lab.update(t)


def runexperiment(
    function: Callable[[float, Any], object], *args: Any, **kwargs: Any
) -> Experiment:
    """Run an :class:`Experiment` of ``args``, ``kwargs``, calling ``function(t, lab)`` each second.

    Returns
    -------
    Experiment
        The finished experiment (its ``historian`` holds the record).
    """
    with Experiment(*args, **kwargs) as experiment:
        assert experiment.lab is not None
        for t in experiment.clock():
            function(t, experiment.lab)
    return experiment
