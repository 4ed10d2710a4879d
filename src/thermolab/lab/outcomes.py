"""What :class:`~thermolab.lab.service.Lab`'s calls return.

The start-up report, an output reading, an input's result: plain values,
apart from the lab's wiring, so that the HTTP schemas and the fleet's
workers can take them without the services behind them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime

__all__ = ["InputResult", "OutputReading", "StartupReport"]


@dataclass(frozen=True, slots=True)
class StartupReport:
    """What :meth:`~thermolab.lab.service.Lab.start` found.

    Attributes
    ----------
    teachers : int
        Teacher accounts in the database (0: tell the operator how to add one).
    faults : dict
        Rig id -> why the rig could not be opened.
    """

    teachers: int
    faults: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class OutputReading:
    """A rig's output as :meth:`~thermolab.lab.service.Lab.read_output` gives it.

    Attributes
    ----------
    rig_id : str
    y : float or None
        The output (``None``: never read, e.g. the rig is off).
    at : datetime or None
        When it was read.
    u : float or None
        The input the lab last applied.
    fresh : bool
        Read from the device for this request (the controller's reads).
    channels : mapping of str to float or None
        The rig's further channels (a kit's ``t2`` read with ``y``, ``q2``'s
        level); empty for a rig that declares none.
    """

    rig_id: str
    y: float | None
    at: datetime | None
    u: float | None
    fresh: bool
    channels: Mapping[str, float | None] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class InputResult:
    """An input command as the lab handled it.

    Attributes
    ----------
    rig_id : str
    u : float
        The value asked for.
    applied : float or None
        The value the device applied, or ``None`` when it reached no device.
    at : datetime
        When the command was accepted.
    command_id : int
    run_id : int or None
        The run the input went to, if one was going.
    """

    rig_id: str
    u: float
    applied: float | None
    at: datetime
    command_id: int
    run_id: int | None = None
