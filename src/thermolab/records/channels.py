"""Named channels: what a record's columns are (name, unit, role), declared once."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

from thermolab.errors import InvalidParameterError

__all__ = [
    "INDEX",
    "INPUT",
    "JITTER",
    "KNOWN_CHANNELS",
    "LATENESS",
    "OUTPUT",
    "REQUIRED",
    "RUN_CHANNELS",
    "TIME",
    "T_READ",
    "ChannelRole",
    "ChannelSpec",
    "channel_names",
    "unit_symbol",
]

ChannelRole = Literal["time", "input", "output", "setpoint", "error", "index", "timing", "other"]
"""What a channel is: the time axis, the input applied, the output read, a set
point or error signal of a controller, the sample index, the runner's timing
measurements, or anything else a rig publishes."""
_ROLES: tuple[str, ...] = ChannelRole.__args__  # type: ignore[attr-defined]


@dataclass(frozen=True, slots=True)
class ChannelSpec:
    """One named channel of a record.

    Parameters
    ----------
    name : str
        The column name (lower case letters, digits and ``_``; starts with a letter).
    unit : str, optional
        The unit (``"s"``, ``"V"``, ``"degC"``, ``""`` for a count).
    role : ChannelRole, optional
        What the channel is (default ``"other"``).
    description : str, optional
        One line for people (tooltips, ``--help``).
    integer : bool, optional
        Written as an integer (a sample index).
    digits : int or None, optional
        Significant digits written (default ``None``: the shortest text that
        reads back to the same double).

    Raises
    ------
    InvalidParameterError
        If the name, role or digits are not allowed.

    Examples
    --------
    >>> ChannelSpec("u2", "V", "input", "second heater").to_dict()
    {'name': 'u2', 'unit': 'V', 'role': 'input', 'description': 'second heater'}
    >>> ChannelSpec("2u")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    thermolab.errors.InvalidParameterError: channel name '2u' must start with a lower-case ...
    """

    name: str
    unit: str = ""
    role: ChannelRole = "other"
    description: str = ""
    integer: bool = False
    digits: int | None = None

    def __post_init__(self) -> None:
        name = self.name
        if not (
            isinstance(name, str)
            and name[:1].isascii()
            and name[:1].islower()
            and all(c.isascii() and (c.islower() or c.isdigit() or c == "_") for c in name)
        ):
            raise InvalidParameterError(
                f"channel name {name!r} must start with a lower-case letter and hold only "
                "a-z, 0-9 and _"
            )
        if self.role not in _ROLES:
            raise InvalidParameterError(
                f"channel {name!r}: unknown role {self.role!r}; allowed: {', '.join(_ROLES)}"
            )
        if self.digits is not None and not (
            isinstance(self.digits, int) and 1 <= self.digits <= 17
        ):
            raise InvalidParameterError(
                f"channel {name!r}: digits must be an integer in 1..17 or None, got {self.digits!r}"
            )

    def to_dict(self) -> dict[str, str]:
        """Return ``{"name", "unit", "role", "description"}`` (JSON-ready).

        Examples
        --------
        >>> TIME.to_dict()
        {'name': 't', 'unit': 's', 'role': 'time', 'description': 'scheduled time of the sample'}
        """
        return {
            "name": self.name,
            "unit": self.unit,
            "role": self.role,
            "description": self.description,
        }


TIME = ChannelSpec("t", "s", "time", "scheduled time of the sample", digits=12)
INPUT = ChannelSpec("u", "V", "input", "input applied from this sample to the next")
OUTPUT = ChannelSpec("y", "V", "output", "output read at this sample")
INDEX = ChannelSpec("k", "", "index", "sample index", integer=True)
T_READ = ChannelSpec("t_read", "s", "timing", "when the rig took the reading")
JITTER = ChannelSpec("jitter", "s", "timing", "t_read - t, the acquisition's timing error")
LATENESS = ChannelSpec("lateness", "s", "timing", "how late the loop woke for this sample")

REQUIRED: tuple[ChannelSpec, ...] = (TIME, INPUT, OUTPUT)
"""The channels every record has, first, in this order (what the methods need)."""

RUN_CHANNELS: tuple[ChannelSpec, ...] = (*REQUIRED, INDEX, T_READ, JITTER, LATENESS)
"""The channels of a runner's record, in column order (``t,u,y,k,t_read,jitter,lateness``)."""

KNOWN_CHANNELS: Mapping[str, ChannelSpec] = {c.name: c for c in RUN_CHANNELS}
"""Channels recognised by name when a file is read (others get role ``"other"``)."""


def channel_names(channels: Iterable[ChannelSpec]) -> tuple[str, ...]:
    """The column names of a channel list.

    Examples
    --------
    >>> ",".join(channel_names(RUN_CHANNELS))
    't,u,y,k,t_read,jitter,lateness'
    """
    return tuple(c.name for c in channels)


def checked_channels(channels: Sequence[ChannelSpec]) -> tuple[ChannelSpec, ...]:
    """``channels`` as a tuple, checked: ``t, u, y`` first, no name twice."""
    channels = tuple(channels)
    names = channel_names(channels)
    if names[:3] != channel_names(REQUIRED):
        raise InvalidParameterError(
            f"a record's channels start with t, u, y; got {', '.join(names) or 'none'}"
        )
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise InvalidParameterError(f"channel {name!r} appears twice in the record")
        seen.add(name)
    return channels


#: Units as people write them; a record and a rig spell degrees Celsius ``degC``
#: (plain ASCII, for files and the API), a person reads ``°C``.
_UNIT_SYMBOLS: Mapping[str, str] = {"degC": "°C"}


def unit_symbol(unit: str) -> str:
    """A channel's unit as a person reads it (a heading, a picture, a message).

    The same rule as the browser's ``unitSymbol`` (``js/quantities.js``).

    Examples
    --------
    >>> unit_symbol("degC"), unit_symbol("%"), unit_symbol("V")
    ('°C', '%', 'V')
    """
    return _UNIT_SYMBOLS.get(unit, unit)
