"""The rig contract: what every rig (digital twin, hardware driver) is and provides.

A rig has one actuator input ``u`` (volts for the paper's box, percent of
heater power for a TCLab kit) and one sensor output ``y``. The interface is the
:class:`Rig` protocol, with what it describes (:class:`RigInfo`), reads
(:class:`Reading`) and goes through (:class:`RigState`);
:class:`~thermolab.rigs.base.BaseRig` implements the parts every rig shares.

Lifecycle (:class:`RigState`)::

    IDLE --power_on()--> POWERED --power_off()--> IDLE
    IDLE/POWERED --fault--> FAULTED --clear_fault()--> IDLE
    any --close()--> CLOSED   (terminal)

In every state but POWERED the actuator is at the rig's safe input value, and
every further actuator the rig's kind declares (a twin's disturbance fan:
:class:`FanSpec`) is at its declared ``default``: powering off, a fault and
closing put them all there, so a rig powered off and on again is the rig its
declaration describes, whatever a run or a user set before (issue #23).
An operation that is not allowed in the current state raises
:class:`~thermolab.errors.RigStateError` naming the state and what to do;
``power_off()`` and ``close()`` are always allowed and idempotent.
"""

from __future__ import annotations

import enum
from dataclasses import asdict, dataclass
from types import TracebackType
from typing import Any, Protocol, Self, runtime_checkable

from thermolab.rigs.clock import Clock

__all__ = ["FanSpec", "Reading", "Rig", "RigInfo", "RigState"]


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

    @property
    def input_range(self) -> tuple[float, float]:
        """``(input_min, input_max)``."""
        return (self.input_min, self.input_max)

    def to_dict(self) -> dict[str, Any]:
        """Return the fields as a JSON-ready dictionary."""
        return asdict(self)


@dataclass(frozen=True, slots=True)
class FanSpec:
    """A rig's disturbance fan: a second actuator, apart from the controlled input.

    A rig kind that has one opens rigs with ``set_fan(percent, *, at=None)``
    and a ``fan`` property (the twin: :meth:`thermolab.rigs.twin.TwinRig.set_fan`),
    and puts the fan at ``default`` in its safe state (see the module's notes).

    Attributes
    ----------
    unit : str
    minimum, maximum : float
        The levels ``set_fan`` accepts, inclusive.
    default : float
        The level the rig rests at: where powering off, a fault and closing
        put the fan, and so where every run and every turn starts from.
    description : str

    Examples
    --------
    >>> FanSpec().default
    0.0
    """

    unit: str = "%"
    minimum: float = 0.0
    maximum: float = 100.0
    default: float = 0.0
    description: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Return ``{"unit", "minimum", "maximum", "default", "description"}``."""
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

    Examples
    --------
    >>> Reading(1.25, 3.0)
    Reading(value=1.25, t=3.0)
    """

    value: float
    t: float


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
