"""The rig contract: what every rig (digital twin, hardware driver) is and provides.

A rig has one actuator input ``u`` (volts for the paper's box, percent of
heater power for a TCLab kit) and one sensor output ``y``: the primary pair,
which runs, identification and control use. It may declare further channels
in its :class:`RigInfo`, once: further inputs (:class:`InputChannel`: a
twin's disturbance fan, a kit's heater 2) that :meth:`Rig.set_channel` sets
and :meth:`Rig.level` reads back, and further outputs (:class:`OutputChannel`:
a kit's sensor 2) that every :class:`Reading` carries beside ``value``. The interface is the
:class:`Rig` protocol, with what it describes (:class:`RigInfo`), reads
(:class:`Reading`) and goes through (:class:`RigState`);
:class:`~thermolab.rigs.base.BaseRig` implements the parts every rig shares.

Lifecycle (:class:`RigState`)::

    IDLE --power_on()--> POWERED --power_off()--> IDLE
    IDLE/POWERED --fault--> FAULTED --clear_fault()--> IDLE
    any --close()--> CLOSED   (terminal)

In every state but POWERED the actuator is at the rig's safe input value, and
every further input the rig declares (:attr:`RigInfo.further_inputs`: a
twin's fan, a kit's heater 2) is at its declared ``default``: powering off, a fault and
closing put them all there, so a rig powered off and on again is the rig its
declaration describes, whatever a run or a user set before (issue #23).
An operation that is not allowed in the current state raises
:class:`~thermolab.errors.RigStateError` naming the state and what to do;
``power_off()`` and ``close()`` are always allowed and idempotent.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from types import MappingProxyType, TracebackType
from typing import Any, Protocol, Self, runtime_checkable

from thermolab.errors import ChannelNotOnRigError, InvalidParameterError, LoopPairNotOnRigError
from thermolab.rigs.clock import Clock

__all__ = [
    "PRIMARY_PAIR",
    "InputChannel",
    "OutputChannel",
    "Reading",
    "Rig",
    "RigInfo",
    "RigState",
]

#: The primary pair's names (the record's columns): a closed loop's pair unless it names another.
PRIMARY_PAIR = ("u", "y")


class RigState(enum.Enum):
    """Lifecycle state of a rig.

    Attributes
    ----------
    IDLE
        Open and readable; the actuator is held at its safe value and
        ``apply`` is refused.
    POWERED
        ``apply`` drives the actuator.
    FAULTED
        A fault is latched (see ``fault()``); the actuator is at its safe value,
        ``apply`` and ``power_on`` are refused until ``clear_fault()``.
    CLOSED
        Released for good; only ``close()``, ``power_off()``, ``fault()``,
        ``describe()`` and ``state`` still work.
    """

    IDLE = "idle"
    POWERED = "powered"
    FAULTED = "faulted"
    CLOSED = "closed"


@dataclass(frozen=True, slots=True)
class InputChannel:
    """A further input of a rig, apart from the primary input ``u``.

    A twin's disturbance fan, a kit's heater 2. The rig sets it with
    :meth:`Rig.set_channel` and reads it back with :meth:`Rig.level`, and
    puts it at ``default`` in its safe state (see the module's notes).

    Attributes
    ----------
    name : str
        The channel's name: the column of a record, the key of a command.
    unit : str
    minimum, maximum : float
        The levels ``set_channel`` accepts, inclusive.
    default : float
        The level the rig rests at: where powering off, a fault and closing
        put the input, and so where every run and every turn starts from.
    description : str
    recorded : bool
        ``True``: every run records the level as a channel. ``False``: only a
        closed-loop run does (the paper's twins' fan, a disturbance for a
        controller: the open-loop records of the paper stay ``t,u,y``).
    sensor : str or None
        The further output this input drives (a kit's heater 2 heats sensor 2,
        ``t2``): with it, a pair a closed loop may control
        (:attr:`RigInfo.loop_pairs`); ``None``: a disturbance only (the fan).

    Examples
    --------
    >>> heater = InputChannel("q2", description="heater 2")
    >>> heater.range, heater.default
    ((0.0, 100.0), 0.0)
    """

    name: str
    unit: str = "%"
    minimum: float = 0.0
    maximum: float = 100.0
    default: float = 0.0
    description: str = ""
    recorded: bool = True
    sensor: str | None = None

    @property
    def range(self) -> tuple[float, float]:
        """``(minimum, maximum)``."""
        return (self.minimum, self.maximum)

    def to_dict(self) -> dict[str, Any]:
        """Return the fields as a JSON-ready dictionary."""
        return asdict(self)


@dataclass(frozen=True, slots=True)
class OutputChannel:
    """A further output of a rig, apart from the primary output ``y`` (a kit's sensor 2).

    Every :class:`Reading` of the rig carries its value (``Reading.further``);
    above ``limit`` the rig faults as for ``y`` (over-temperature).

    Attributes
    ----------
    name : str
        The channel's name: the column of a record.
    unit : str
    limit : float or None
        The value above which the rig faults and goes to its safe state.
    description : str

    Examples
    --------
    >>> OutputChannel("t2", "degC", 90.0).limit
    90.0
    """

    name: str
    unit: str
    limit: float | None = None
    description: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Return the fields as a JSON-ready dictionary."""
        return asdict(self)


@dataclass(frozen=True, slots=True)
class RigInfo:
    """What a rig is and what it accepts.

    Attributes
    ----------
    name : str
        Human-readable name (``"paper twin"``, ``"TCLab on /dev/ttyACM0"``).
    kind : str
        Implementation family: ``"twin"`` or ``"tclab"``.
    input_min, input_max : float
        The allowed range of ``apply(u)``, inclusive.
    input_unit : str
        Unit of the input (``"V"``, ``"%"``).
    output_unit : str
        Unit of the output (``"V"``, ``"degC"``).
    safe_input : float
        The input value the rig is left at when idle, faulted or closed.
    output_limit : float or None
        Output above which the rig faults and goes to its safe state
        (over-temperature); ``None`` when the rig has none.
    description : str
        One sentence for a user interface (``""`` if none).
    further_inputs : tuple of InputChannel
        The inputs besides ``u`` (none for most rigs).
    further_outputs : tuple of OutputChannel
        The outputs besides ``y``.

    Examples
    --------
    >>> info = RigInfo("demo", "twin", -10.0, 10.0, "V", "V", 0.0, None)
    >>> info.input_range
    (-10.0, 10.0)
    >>> info.to_dict()["input_unit"]
    'V'
    """

    name: str
    kind: str
    input_min: float
    input_max: float
    input_unit: str
    output_unit: str
    safe_input: float
    output_limit: float | None
    description: str = ""
    further_inputs: tuple[InputChannel, ...] = ()
    further_outputs: tuple[OutputChannel, ...] = ()

    @property
    def input_range(self) -> tuple[float, float]:
        """``(input_min, input_max)``."""
        return (self.input_min, self.input_max)

    @property
    def inputs(self) -> Mapping[str, InputChannel]:
        """:attr:`further_inputs` by name."""
        return MappingProxyType({c.name: c for c in self.further_inputs})

    @property
    def outputs(self) -> Mapping[str, OutputChannel]:
        """:attr:`further_outputs` by name."""
        return MappingProxyType({c.name: c for c in self.further_outputs})

    @property
    def loop_pairs(self) -> tuple[tuple[str, str], ...]:
        """The ``(input, output)`` pairs a closed loop may control, the primary pair first.

        ``("u", "y")``, then each further input that names a further output of
        the rig as its ``sensor`` (a kit's ``("q2", "t2")``).

        Examples
        --------
        >>> from thermolab.rigs import tclab_info
        >>> tclab_info(None).loop_pairs
        (('u', 'y'), ('q2', 't2'))
        """
        further = tuple(
            (c.name, c.sensor)
            for c in self.further_inputs
            if c.sensor is not None and c.sensor in self.outputs
        )
        return (PRIMARY_PAIR, *further)

    def check_loop_pair(self, heater: str, sensor: str) -> tuple[str, str]:
        """Return ``(heater, sensor)`` if it is one of :attr:`loop_pairs`.

        Raises
        ------
        LoopPairNotOnRigError
            Naming the pairs the rig has (422 ``loop_pair_not_on_rig``).

        Examples
        --------
        >>> info = RigInfo("box", "twin", -10, 10, "V", "V", 0, None)
        >>> info.check_loop_pair("q2", "t2")
        Traceback (most recent call last):
        ...
        thermolab.errors.LoopPairNotOnRigError: rig 'box' has no heater and sensor q2/t2 ... u/y
        """
        pair = (heater, sensor)
        pairs = self.loop_pairs
        if pair not in pairs:
            raise LoopPairNotOnRigError(
                f"rig {self.name!r} has no heater and sensor {heater}/{sensor} to control in "
                f"closed loop; its pairs: {', '.join(f'{i}/{o}' for i, o in pairs)}"
            )
        return pair

    def further_level(self, name: str, value: object) -> float:
        """Return ``value`` as a level of the further input ``name``.

        Raises
        ------
        ChannelNotOnRigError
            If the rig has no such input (an :class:`InvalidParameterError`).
        InvalidParameterError
            If ``value`` is not a number in the input's range.

        Examples
        --------
        >>> info = RigInfo("kit", "tclab", 0, 100, "%", "degC", 0, 90,
        ...                further_inputs=(InputChannel("q2"),))
        >>> info.further_level("q2", "40")
        40.0
        >>> info.further_level("q2", 140)
        Traceback (most recent call last):
        ...
        thermolab.errors.InvalidParameterError: q2 of 'kit' takes 0-100 %, got 140
        """
        channel = self.inputs.get(name)
        if channel is None:
            has = ", ".join(self.inputs) or "none"
            raise ChannelNotOnRigError(
                f"rig {self.name!r} has no input {name!r}; its further inputs: {has}"
            )
        try:
            level = float(value)  # type: ignore[arg-type]  # anything a request carried
        except (TypeError, ValueError):
            level = math.nan
        if not (math.isfinite(level) and channel.minimum <= level <= channel.maximum):
            raise InvalidParameterError(
                f"{name} of {self.name!r} takes {channel.minimum:g}-{channel.maximum:g} "
                f"{channel.unit}, got {value!r}"
            )
        return level

    def to_dict(self) -> dict[str, Any]:
        """Return the fields as a JSON-ready dictionary."""
        return asdict(self)


@dataclass(frozen=True, slots=True)
class Reading:
    """One sensor reading.

    Attributes
    ----------
    value : float
        The output in the rig's output unit.
    t : float
        The rig clock's time when the reading was taken, as the host knows it.
        (A twin with sample-time jitter samples its state at a slightly
        different, undisclosed instant, as a real acquisition board does.)
    further : mapping of str to float
        Each further output's value at the same instant, by name
        (:attr:`RigInfo.further_outputs`; empty for a rig that has none).

    Examples
    --------
    >>> Reading(1.25, 3.0)
    Reading(value=1.25, t=3.0)
    >>> Reading(30.5, 3.0, {"t2": 24.1}).further["t2"]
    24.1
    """

    value: float
    t: float
    further: Mapping[str, float] = field(default_factory=dict, repr=False)


@runtime_checkable
class Rig(Protocol):
    """The interface every rig implements.

    Notes
    -----
    Use as a context manager; leaving the ``with`` block, by any way, closes
    the rig and leaves its actuator at the safe input value.
    """

    @property
    def state(self) -> RigState:
        """The lifecycle state."""
        ...

    @property
    def powered(self) -> bool:
        """``True`` when ``apply`` drives the actuator (state POWERED)."""
        ...

    @property
    def clock(self) -> Clock:
        """The clock that timestamps readings (and drives a twin's physics)."""
        ...

    def describe(self) -> RigInfo:
        """Return what the rig is and what it accepts."""
        ...

    def power_on(self) -> None:
        """Allow ``apply`` to drive the actuator (IDLE -> POWERED)."""
        ...

    def power_off(self) -> None:
        """Put the actuator at its safe value and refuse ``apply`` (idempotent)."""
        ...

    def apply(self, u: float, *, at: float | None = None) -> float:
        """Set the actuator input; return the value actually applied.

        ``at``: the scheduled sample instant this input belongs to (a twin
        applies it exactly there; hardware applies it now).
        """
        ...

    def read(self, *, at: float | None = None) -> Reading:
        """Read the sensor output, with the clock time of the reading.

        ``at``: the scheduled sample instant (a twin samples exactly there;
        hardware samples now).
        """
        ...

    def set_channel(self, name: str, value: float, *, at: float | None = None) -> float:
        """Set the further input ``name`` (:attr:`RigInfo.further_inputs`); return the level set.

        Allowed while POWERED; ``at`` as for :meth:`apply`.
        """
        ...

    def level(self, name: str) -> float:
        """The further input ``name``'s level now."""
        ...

    def fault(self) -> str | None:
        """Return the reason of a latched fault, or ``None``."""
        ...

    def clear_fault(self) -> None:
        """Acknowledge a fault and return to IDLE if its cause is gone."""
        ...

    def close(self) -> None:
        """Put the actuator at its safe value and release the rig (idempotent)."""
        ...

    def __enter__(self) -> Self: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...
