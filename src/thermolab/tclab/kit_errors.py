"""What a lab rig cannot do that the kit does: the errors ``TCLab`` raises.

Each keeps the built-in base the ``tclab`` package raises in its place, so a
notebook's ``except`` clause catches it as it would on a kit.
"""

from __future__ import annotations

__all__ = [
    "AlreadyConnectedError",
    "NotAKitError",
    "NotOnThisRigError",
    "PortError",
    "SecondHeaterError",
]


class NotOnThisRigError(NotImplementedError):
    """What the ``tclab`` package does on a kit, this lab rig cannot (the message says why).

    A ``NotImplementedError`` (as :class:`SecondHeaterError` always was): the name
    exists and works on a kit; it is this rig that lacks it, not the call that is wrong.
    """


class SecondHeaterError(NotOnThisRigError):
    """The rig has one heater and one sensor: ``Q2``/``T2``/``U2``/``P2`` do not exist there.

    A rig that declares heater 2 (``q2``) and sensor 2 (``t2``) — a kit, the
    kit's twin ``sim:kit`` — has them all.
    """


class NotAKitError(ValueError):
    """The rig is not a heater (%) and a temperature sensor (°C): ``TCLab`` cannot drive it."""


class AlreadyConnectedError(RuntimeError):
    """This process already has an open ``TCLab`` on that rig (close it first), as in ``tclab``."""


class PortError(RuntimeError):
    """``TCLab(port=...)``: a lab rig has no serial port (the ``tclab`` package's RuntimeError)."""
