"""``open_rig``: a rig from the one-line specification used by the CLI and the server."""

from __future__ import annotations

from typing import Any

from thermolab.rigs.clock import Clock
from thermolab.rigs.contract import Rig
from thermolab.rigs.spec import RIG_SPECS, RigSpec

__all__ = ["RIG_SPECS", "open_rig"]


def open_rig(
    spec: str | RigSpec, *, clock: Clock | None = None, seed: int | None = None, **options: Any
) -> Rig:
    """Open the rig named by ``spec``.

    Parameters
    ----------
    spec : str or RigSpec
        ``sim`` (the paper's twin, noise-free), ``sim:PRESET`` (a twin preset:
        ``paper``, ``paper-practical``, ``tclab``), ``tclab`` (a TCLab kit,
        auto-detected) or ``tclab:PORT`` (a kit on that serial port); parsed
        by :meth:`RigSpec.parse <thermolab.rigs.spec.RigSpec.parse>`.
    clock : Clock, optional
        The clock of the rig (default: real time).
    seed : int, optional
        Seed of a twin's realism; ignored by hardware.
    **options
        Passed to the rig's constructor: :class:`~thermolab.rigs.twin.TwinRig`
        accepts ``realism`` and any :class:`~thermolab.rigs.twin.TwinParams`
        field, :class:`~thermolab.rigs.tclab.TCLabRig` its keyword arguments
        (``timeout``, ``max_temperature``, ``watchdog``...).

    Returns
    -------
    Rig
        An open rig in state IDLE.

    Raises
    ------
    InvalidParameterError
        For an unknown specification, preset or option.
    RigError
        If a kit cannot be opened or found.

    Examples
    --------
    >>> from thermolab.rigs.clock import VirtualClock
    >>> with open_rig("sim:tclab", clock=VirtualClock(), seed=1) as rig:
    ...     rig.describe().input_unit, rig.describe().output_unit
    ('%', 'degC')
    >>> open_rig("lab")
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: unknown rig 'lab'; use one of: sim, ...
    """
    return RigSpec.parse(spec).open(clock=clock, seed=seed, **options)
