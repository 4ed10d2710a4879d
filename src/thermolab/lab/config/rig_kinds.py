"""Rig specs as the lab reads them: :class:`thermolab.rigs.RigSpec`, and the published range.

The rigs layer owns the spec grammar (:meth:`RigSpec.parse`) and each kind's
units, input range and safe input (:meth:`RigSpec.describe`, which opens
nothing). The lab adds only what is its own: a configured ``input_range``
narrowing the rig's range, and whether a driver is attached (``live``).
:func:`parse_rig_spec` turns the rigs layer's error into a
:class:`~thermolab.errors.ConfigError` so the configuration reader can name
the key.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from thermolab.errors import ConfigError, InvalidParameterError
from thermolab.lab.config.model import RigConfig
from thermolab.rigs import RigInfo, RigSpec

__all__ = [
    "ActuatorLevel",
    "PublishedRig",
    "narrow_range",
    "parse_rig_spec",
    "published_defaults",
]


@dataclass(frozen=True, slots=True)
class ActuatorLevel:
    """One actuator of a rig besides its input (a twin's fan), as it is and as declared.

    Attributes
    ----------
    name : str
        As the rig's kind declares it (:attr:`thermolab.rigs.RigSpec.actuators`).
    unit : str
    default : float
        Its declared default: where every turn and run starts from.
    level : float or None
        Its level now (``None``: not known here, e.g. on a rig host).
    """

    name: str
    unit: str
    default: float
    level: float | None


@dataclass(frozen=True, slots=True)
class PublishedRig:
    """What the lab tells users a rig accepts.

    Attributes
    ----------
    input_min, input_max : float
        The allowed input range (the rig's own, narrowed by the configuration).
    input_unit, output_unit : str
    safe_input : float
        Input the rig rests at without a controller.
    live : bool
        ``True`` when a driver is attached and inputs reach a device.
    speedup : float or None
        Times real time the rig runs: 1 for hardware, a twin the lab runs its
        ``twin_speedup``, a twin on a rig host its host's ``--speedup`` once the
        host has said it (``None`` before). :meth:`DeviceHub.published
        <thermolab.lab.rigs.devices.DeviceHub.published>` fills it in.
    actuators : tuple of ActuatorLevel
        Every actuator besides the input, read now (filled in like ``speedup``).
    """

    input_min: float
    input_max: float
    input_unit: str
    output_unit: str
    safe_input: float
    live: bool
    speedup: float | None = None
    actuators: tuple[ActuatorLevel, ...] = ()

    @classmethod
    def from_dict(cls, fields: Mapping[str, Any]) -> PublishedRig:
        """Rebuild one from its ``dataclasses.asdict`` (another worker's, through the fleet bus).

        Examples
        --------
        >>> fan = ActuatorLevel("fan", "%", 0.0, 50.0)
        >>> rig = PublishedRig(0.0, 10.0, "V", "V", 0.0, True, 1.0, (fan,))
        >>> PublishedRig.from_dict(dataclasses.asdict(rig)) == rig
        True
        """
        actuators = tuple(ActuatorLevel(**level) for level in fields.get("actuators") or ())
        return cls(**{**fields, "actuators": actuators})

    @classmethod
    def of(cls, info: RigInfo, *, live: bool) -> PublishedRig:
        """What a rig described by ``info`` accepts, before the configuration narrows it."""
        return cls(
            info.input_min,
            info.input_max,
            info.input_unit,
            info.output_unit,
            info.safe_input,
            live,
        )


def parse_rig_spec(spec: str) -> tuple[str, str | None]:
    """Split a rig spec into its kind and argument with :meth:`RigSpec.parse`.

    Parameters
    ----------
    spec : str
        ``sim``, ``sim:PRESET``, ``tclab`` or ``tclab:PORT`` (see
        :mod:`thermolab.rigs.spec`).

    Returns
    -------
    tuple
        ``(kind, argument)``; a bare word takes its kind's default argument
        (``sim`` is ``sim:paper``; ``tclab`` keeps ``None``: auto-detect).

    Raises
    ------
    ConfigError
        With the rigs layer's message, when the spec is not understood.

    Examples
    --------
    >>> parse_rig_spec("tclab:/dev/ttyUSB0")
    ('tclab', '/dev/ttyUSB0')
    >>> parse_rig_spec("sim")
    ('sim', 'paper')
    """
    parsed = _spec(spec)
    return (parsed.kind, parsed.argument)


def _spec(spec: str) -> RigSpec:
    try:
        return RigSpec.parse(spec)
    except InvalidParameterError as exc:
        raise ConfigError(str(exc)) from None


def published_defaults(rig: RigConfig) -> PublishedRig:
    """Return the published range of a rig without opening it.

    Units, range and safe input are the rig kind's own
    (:meth:`RigSpec.describe`); a configured ``input_range`` narrows the range.

    Raises
    ------
    ConfigError
        If the spec is not understood or the configured range is not inside the
        rig's own.

    Examples
    --------
    >>> tclab = published_defaults(RigConfig("a", "A", "sim:tclab"))
    >>> tclab.input_min, tclab.input_max, tclab.input_unit, tclab.output_unit
    (0.0, 100.0, '%', 'degC')
    """
    return narrow_range(PublishedRig.of(_spec(rig.spec).describe(), live=False), rig)


def narrow_range(base: PublishedRig, rig: RigConfig) -> PublishedRig:
    """``base`` narrowed to the rig's configured ``input_range`` (checked to lie inside)."""
    if rig.input_range is None:
        return base
    low, high = rig.input_range
    if low < base.input_min or high > base.input_max:
        raise ConfigError(
            f"rig {rig.id!r}: input_range [{low:g}, {high:g}] goes beyond the rig's own range "
            f"[{base.input_min:g}, {base.input_max:g}] {base.input_unit}"
        )
    safe = min(max(base.safe_input, low), high)
    return dataclasses.replace(base, input_min=low, input_max=high, safe_input=safe)
