"""Rig kinds as the lab knows them: the spec grammar and each kind's units and ranges.

The one place the lab reads a rig spec (``sim``, ``sim:PRESET``, ``tclab``,
``tclab:PORT``) and the one place it states a kind's units and input range,
so that reading them from the rigs layer instead is a change here only.
"""

from __future__ import annotations

from dataclasses import dataclass

from thermolab.errors import ConfigError
from thermolab.lab.config.model import RigConfig
from thermolab.rigs import PRESETS, RIG_SPECS

__all__ = ["PublishedRig", "narrow_range", "parse_rig_spec", "published_defaults"]


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
    """

    input_min: float
    input_max: float
    input_unit: str
    output_unit: str
    safe_input: float
    live: bool


def parse_rig_spec(spec: str) -> tuple[str, str | None]:
    """Split a rig spec into its kind and argument, checking it names a known rig.

    Parameters
    ----------
    spec : str
        ``sim`` (the paper's twin), ``sim:PRESET`` (a twin preset of
        :data:`thermolab.rigs.PRESETS`), ``tclab`` (a kit, auto-detected) or
        ``tclab:PORT``.

    Returns
    -------
    tuple
        ``(kind, argument)``: ``("sim", None)``, ``("sim", "tclab")``,
        ``("tclab", "/dev/ttyUSB0")``.

    Raises
    ------
    ConfigError
        If the spec is not one of the forms above.

    Examples
    --------
    >>> parse_rig_spec("tclab:/dev/ttyUSB0")
    ('tclab', '/dev/ttyUSB0')
    >>> parse_rig_spec("sim")
    ('sim', None)
    """
    kind, sep, arg = spec.strip().partition(":")
    arg = arg.strip()
    if kind == "sim" and not sep:
        return ("sim", None)
    if kind == "sim" and arg in PRESETS:
        return ("sim", arg)
    if kind == "tclab" and not sep:
        return ("tclab", None)
    if kind == "tclab" and arg:
        return ("tclab", arg)
    raise ConfigError(f"rig spec {spec!r} is not understood; use one of: {', '.join(RIG_SPECS)}")


def published_defaults(rig: RigConfig) -> PublishedRig:
    """Return the published range of a rig without opening it.

    The paper's box takes -10..10 V and reports volts; TCLab kits (and their
    twin) take 0..100 % heater power and report degrees Celsius. A configured
    ``input_range`` narrows the range.

    Raises
    ------
    ConfigError
        If the configured range is not inside the rig's own.

    Examples
    --------
    >>> tclab = published_defaults(RigConfig("a", "A", "sim:tclab"))
    >>> tclab.input_min, tclab.input_max, tclab.input_unit, tclab.output_unit
    (0.0, 100.0, '%', 'degC')
    """
    kind, arg = parse_rig_spec(rig.spec)
    if kind == "tclab" or arg == "tclab":
        base = PublishedRig(0.0, 100.0, "%", "degC", 0.0, False)
    else:
        base = PublishedRig(-10.0, 10.0, "V", "V", 0.0, False)
    return narrow_range(base, rig)


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
    return PublishedRig(low, high, base.input_unit, base.output_unit, safe, base.live)
