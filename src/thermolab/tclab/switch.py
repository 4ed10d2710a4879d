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

from thermolab.client import ENV_URL, LabRequestError
from thermolab.tclab.labtime import labtime
from thermolab.tclab.model import TCLabModel
from thermolab.tclab.remote import TCLab

__all__ = ["SpeedupRefusedError", "setup", "uses_lab_twin"]


def uses_lab_twin(twin: bool | None = None) -> bool:
    """Whether ``connected=False`` means the lab's twin: ``twin``, else ``$THERMOLAB_URL`` set."""
    return bool(os.environ.get(ENV_URL)) if twin is None else twin


class SpeedupRefusedError(ValueError):
    """The lab's twin does not allow the speed-up ``setup(connected=False, speedup=...)`` asked for.

    The message names the rig and what it allows: a twin the lab runs allows
    1 up to its teacher's ``twin_speedup``; hardware, or a twin on a rig host,
    only its own pace.
    """


def _pace_turn(kit: TCLab, asked: float) -> None:
    """Run the twin at ``asked`` for this turn (the lab resets it at the turn's end)."""
    if asked == kit.speedup or kit._turn is None:
        return
    try:
        in_force = kit._turn.pace(asked)
    except LabRequestError as exc:
        kit.close()
        raise SpeedupRefusedError(
            f"setup(connected=False, speedup={asked:g}): {exc.detail}"
        ) from exc
    kit.speedup = in_force
    held = f"rig {kit.rig_id!r} of the lab at {kit.lab.url} runs at {in_force:g}x"
    labtime.hold(in_force, held if in_force != 1 else None)
    if in_force == 1:
        labtime.set_rate(1)


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
        runs at it (``labtime.set_rate(speedup)``). The lab's twin runs at it
        for this script's turn if it allows it — from 1 up to the speed-up its
        teacher set (``twin_speedup``) — and goes back to the teacher's at the
        turn's end; ``clock``/``labtime`` follow it.
    twin : bool, optional
        With ``connected=False``: the lab's twin (``True``) or the offline
        model (``False``); default: the twin when ``$THERMOLAB_URL`` names a lab.

    Raises
    ------
    ValueError
        For a speed-up with ``connected=True`` (a real rig runs in real
        time), or one that is not a positive number; when the class connects,
        :class:`SpeedupRefusedError` for one the lab's rig does not allow.
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
            _pace_turn(self, asked)

    RemoteTCLab.__name__ = RemoteTCLab.__qualname__ = "TCLab"
    if labtime.held_by is None:
        labtime.set_rate(speedup)
    return RemoteTCLab
