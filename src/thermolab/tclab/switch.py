"""``setup``: the ``TCLab`` class to use — a lab rig, the lab's twin, or the offline model.

``setup(connected=True)`` gives the lab's rig (a kit, if the lab has one).
``setup(connected=False, speedup=...)`` gives, as in the ``tclab`` package,
a simulated kit: the lab's twin when a lab is named (``url`` of ``TCLab``
or ``$THERMOLAB_URL``; ``twin=True`` forces it), else the offline
:class:`~thermolab.tclab.TCLabModel` with lab time at ``speedup``.
"""

from __future__ import annotations

import math
import os

from thermolab.client import ENV_URL
from thermolab.tclab.labtime import labtime
from thermolab.tclab.model import TCLabModel
from thermolab.tclab.remote import TCLab

__all__ = ["setup", "speedup_note", "uses_lab_twin"]


def uses_lab_twin(twin: bool | None = None) -> bool:
    """Whether ``connected=False`` means the lab's twin: ``twin``, else ``$THERMOLAB_URL`` set."""
    return bool(os.environ.get(ENV_URL)) if twin is None else twin


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


def setup(
    connected: bool = True, speedup: float = 1, *, twin: bool | None = None
) -> type[TCLab] | type[TCLabModel]:
    """Return the ``TCLab`` class to use, as the ``tclab`` package's ``setup`` does.

    Parameters
    ----------
    connected : bool
        ``True``: a lab rig (a kit, if the lab has one). ``False``: a
        simulated kit — the lab's twin or the offline :class:`TCLabModel`.
    speedup : float
        Only with ``connected=False``: lab time's pace. :class:`TCLabModel`
        runs at it (``labtime.set_rate(speedup)``). The lab's twin runs at its
        own speed-up, which a teacher sets per twin (``twin_speedup``) and a
        client cannot change: connecting then prints which is in force
        (:func:`speedup_note`), and ``clock``/``labtime`` follow it.
    twin : bool, optional
        With ``connected=False``: the lab's twin (``True``) or the offline
        model (``False``); default: the twin when ``$THERMOLAB_URL`` names a lab.

    Raises
    ------
    ValueError
        For a speed-up with ``connected=True`` (a real rig runs in real
        time), or one that is not a positive number.
    """
    if connected and speedup != 1:
        raise ValueError("setup(connected=True) runs a real rig in real time: speedup must be 1")
    if not (isinstance(speedup, int | float) and math.isfinite(speedup) and speedup > 0):
        raise ValueError(f"speedup must be a positive number; got {speedup!r}")
    if not connected and not uses_lab_twin(twin):
        labtime.set_rate(speedup)
        return TCLabModel
    if connected:
        if labtime.held_by is None:
            labtime.set_rate(1)
        return TCLab  # the class itself, as the ``tclab`` package returns its TCLab
    asked = float(speedup)

    class RemoteTCLab(TCLab):
        _simulated = True

        def __init__(self, *args: object, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)  # type: ignore[arg-type]
            note = speedup_note(asked, self.speedup)
            if note is not None:
                print(note)

    RemoteTCLab.__name__ = RemoteTCLab.__qualname__ = "TCLab"
    if labtime.held_by is None:
        labtime.set_rate(speedup)
    return RemoteTCLab
