"""A rig's reference model: the true Ks, Ts and θ a digital twin is built with.

A twin publishes its parameters through its spec (:meth:`thermolab.rigs.RigSpec.defaults`:
``gain``, ``time_constant``) and its first order plus dead time θ
(:attr:`~thermolab.rigs.RigSpec.typical_dead_time`: transport delay plus sensor
lag). Real hardware has no such truth: ``None``.
"""

from __future__ import annotations

from thermolab.lab.assignments.marking import Reference
from thermolab.rigs import RigSpec

__all__ = ["reference_model"]


def reference_model(spec: str) -> Reference | None:
    """The reference model of the rig ``spec`` names, or ``None`` for hardware.

    Examples
    --------
    >>> ref = reference_model("sim")
    >>> round(ref.K, 5), round(ref.tau, 3), ref.theta
    (0.14009, 250.126, 0.0)
    >>> reference_model("tclab:/dev/ttyACM0") is None
    True
    """
    parsed = RigSpec.parse(spec)
    if not parsed.simulated:
        return None
    params = parsed.defaults()
    return Reference(
        float(params["gain"]),
        float(params["time_constant"]),
        parsed.typical_dead_time,
        source=f"the twin {parsed}",
    )
