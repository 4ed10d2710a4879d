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
    "speedup_note",
]


def speedup_note(asked: float, in_force: float) -> str | None:
    """What ``setup(connected=False, speedup=asked)`` tells when the lab's twin runs otherwise.

    A teacher sets each twin's speed-up in the rig's settings (``twin_speedup``,
    on the lab's Teacher page); a client cannot change it, because the twin is
    shared — its clock is the lab's, the same for every user and the lab's own
    runs. ``None`` when they agree.

    Examples
    --------
    >>> speedup_note(20, 20) is None
    True
    >>> print(speedup_note(10, 50))  # doctest: +NORMALIZE_WHITESPACE
    note: the lab's twin runs at 50x real time, not the 10x asked for: a teacher sets each
    twin's speed-up in the rig's settings (twin_speedup) and a client cannot change it;
    clock() and labtime follow 50x
    """
    if asked == in_force:
        return None
    wanted = "real time (1x)" if asked == 1 else f"{asked:g}x"
    return (
        f"note: the lab's twin runs at {in_force:g}x real time, not the {wanted} asked for: "
        "a teacher sets each twin's speed-up in the rig's settings (twin_speedup) and a "
        f"client cannot change it; clock() and labtime follow {in_force:g}x"
    )


def setup(connected: bool = True, speedup: float = 1) -> type[TCLab]:
    """Return the ``TCLab`` class to use, as the ``tclab`` package's ``setup`` does.

    Parameters
    ----------
    connected : bool
        ``True``: a lab rig (a kit, if the lab has one); ``False``: the lab's
        simulated rig (its twin), in place of the kit's offline model.
    speedup : float
        Only with ``connected=False``. The twin runs at its own speed-up,
        which a teacher sets per twin in the rig's settings (``twin_speedup``;
        the rig listing publishes it as ``speedup``); ``clock`` and
        ``labtime`` follow it. A client cannot choose another: when the one in
        force differs from ``speedup`` (the default 1 included), connecting
        prints which is in force and why (:func:`speedup_note`); it is never
        applied.

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
            note = None if connected else speedup_note(asked, self.speedup)
            if note is not None:
                print(note)

    RemoteTCLab.__name__ = RemoteTCLab.__qualname__ = "TCLab"
    return RemoteTCLab
