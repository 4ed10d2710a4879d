"""What drives and listens to a run: input signals, identifiers, extra channels.

The protocols :class:`~thermolab.runner.experiment.Experiment` accepts, and the
block evaluation of a signal that keeps the sampling loop cheap.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from thermolab.records import ChannelSpec
from thermolab.runner.events import SupportsToDict

__all__ = ["ChannelSource", "IdentifierLike", "InputSignal", "signal_table"]

ChannelSource = tuple[ChannelSpec, Callable[[float, float, float], float]]
"""An extra channel of a run: its spec and ``f(t, u, y) -> value``, called once
per sample after the input is applied (TCLab's ``Historian`` sources are the model)."""


@runtime_checkable
class InputSignal(Protocol):
    """An input defined in time: anything with ``value(t) -> float``.

    :class:`thermolab.signals.Signal` (``parse_signal("square:4:6:0.1")``) is one.
    """

    def value(self, t: float) -> float:
        """Return the input at ``t`` seconds after START."""
        ...


@runtime_checkable
class IdentifierLike(Protocol):
    """What the runner needs of an online identifier.

    :class:`thermolab.ident.online.OnlineIdentifier` (from
    :func:`~thermolab.ident.online.make_identifier`, or
    :func:`thermolab.runner.methods.build_identifiers`) is the implementation;
    anything with the same three methods works. ``update`` is called once per
    sample, in order; ``finish`` once at END.
    """

    def update(self, u: float, y: float) -> SupportsToDict | None:
        """Take one sample; return a new estimate or ``None``."""
        ...

    def finish(self) -> SupportsToDict | None:
        """Return the estimate at END (or ``None``)."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """Return the identifier's configuration and state as a dictionary."""
        ...


SIGNAL_BLOCK = 4096


def signal_table(signal: InputSignal, k: int, n: int, dt: float) -> list[float]:
    """The signal at samples ``k ..`` (a block), or ``[]`` if it cannot be vectorised.

    A :class:`thermolab.signals.Signal` evaluates one time as a one-element
    array (tens of microseconds); its ``sample`` over a block costs about the
    same for 4096 times. ``np.arange(k, ...) * dt`` is ``k * dt`` exactly as the
    loop computes it (integers below 2**53 are exact doubles), so the values
    are those ``value(k * dt)`` would give.
    """
    sample = getattr(signal, "sample", None)
    if not callable(sample):
        return []
    times = np.arange(k, min(k + SIGNAL_BLOCK, n), dtype=np.float64) * dt
    values: list[float] = np.asarray(sample(times), dtype=np.float64).tolist()
    return values if len(values) == len(times) else []
