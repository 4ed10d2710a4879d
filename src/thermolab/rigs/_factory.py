"""``open_rig``: a rig from the one-line specification used by the CLI and the server."""

from __future__ import annotations

import inspect
from typing import Any

from thermolab.errors import InvalidParameterError
from thermolab.rigs.base import Rig
from thermolab.rigs.clock import Clock
from thermolab.rigs.tclab import TCLabRig
from thermolab.rigs.twin import PRESETS, TwinRig

__all__ = ["RIG_SPECS", "open_rig"]

#: The accepted forms of a rig specification, for help texts and error messages.
RIG_SPECS = ("sim", *(f"sim:{name}" for name in PRESETS), "tclab", "tclab:PORT")


def _check_options(factory: Any, options: dict[str, Any], kind: str) -> None:
    parameters = inspect.signature(factory).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values()):
        return
    allowed = {
        name
        for name, p in parameters.items()
        if p.kind is inspect.Parameter.KEYWORD_ONLY and name != "clock"
    }
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise InvalidParameterError(
            f"unknown {kind} option(s) {', '.join(unknown)}; allowed: {', '.join(sorted(allowed))}"
        )


def open_rig(
    spec: str, *, clock: Clock | None = None, seed: int | None = None, **options: Any
) -> Rig:
    """Open the rig named by ``spec``.

    Parameters
    ----------
    spec : str
        ``sim`` (the paper's twin, noise-free), ``sim:PRESET`` (a twin preset:
        ``paper``, ``paper-practical``, ``tclab``), ``tclab`` (a TCLab kit,
        auto-detected) or ``tclab:PORT`` (a kit on that serial port).
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
    kind, sep, rest = spec.strip().partition(":")
    if kind == "sim":
        preset = rest if sep else "paper"
        if preset not in PRESETS:
            raise InvalidParameterError(
                f"unknown simulated rig {spec!r}; use one of: "
                + ", ".join(s for s in RIG_SPECS if s.startswith("sim"))
            )
        return TwinRig(preset, clock=clock, seed=seed, **options)
    if kind == "tclab":
        if sep and not rest:
            raise InvalidParameterError(
                f"rig {spec!r} names no port; use 'tclab' to auto-detect or 'tclab:PORT'"
            )
        _check_options(TCLabRig, options, "TCLab")
        return TCLabRig(rest or None, clock=clock, **options)
    raise InvalidParameterError(f"unknown rig {spec!r}; use one of: {', '.join(RIG_SPECS)}")
