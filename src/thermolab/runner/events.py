"""Events of a run: what its sampling loop tells subscribers, in order.

A run publishes four kinds of event, in the order they happen:
:class:`StateEvent` (a lifecycle transition), :class:`SampleEvent` (one sample
taken), :class:`EstimateEvent` (an identifier produced an estimate) and
:class:`FaultEvent` (something went wrong). Every event carries ``seq``, a
number that grows by one per event of the run, so a consumer can see a gap.
Each has ``to_dict()``, its JSON-ready form with ``kind`` first.

How they reach subscribers without delaying sampling is
:mod:`thermolab.runner.event_bus`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar, Protocol, runtime_checkable

from thermolab.jsonsafe import finite_or_none
from thermolab.runner.state import RunState

__all__ = [
    "NO_EXTRA",
    "EstimateEvent",
    "Event",
    "FaultEvent",
    "SampleEvent",
    "StateEvent",
    "SupportsToDict",
]


NO_EXTRA: Mapping[str, float] = MappingProxyType({})
"""The ``extra`` of a sample of a run without extra channels (shared, read-only)."""


@runtime_checkable
class SupportsToDict(Protocol):
    """Anything with a JSON-ready ``to_dict()`` (an identifier's estimate)."""

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary."""
        ...


@dataclass(frozen=True, slots=True)
class SampleEvent:
    """One sample taken.

    Attributes
    ----------
    seq : int
        Event number within the run.
    k : int
        Sample index (0 for the first sample).
    t : float
        Scheduled time of the sample, ``k * dt`` seconds after START.
    t_read : float
        When the rig took the reading, seconds after START.
    u : float
        Input applied from this sample until the next one.
    y : float
        Output read at this sample.
    jitter : float
        ``t_read - t`` (seconds; the acquisition's timing error).
    lateness : float
        How long after its deadline the loop woke for this sample (>= 0).
    extra : mapping of str to float
        The run's other channels (a set point, an error signal, a second
        sensor...), by name; empty when the run declares none (see
        ``Experiment(sources=...)`` and :func:`channels`).
    """

    kind: ClassVar[str] = "sample"
    seq: int
    k: int
    t: float
    t_read: float
    u: float
    y: float
    jitter: float
    lateness: float
    extra: Mapping[str, float] = field(default_factory=lambda: NO_EXTRA)

    def channels(self) -> dict[str, float]:
        """Every channel of the sample by name, in record order.

        The order is :data:`thermolab.records.RUN_CHANNELS`, then ``extra``.

        Examples
        --------
        >>> sample = SampleEvent(3, 0, 0.0, 0.001, 5.0, 0.25, 0.001, 0.0, {"r": 6.0})
        >>> sample.channels()  # doctest: +NORMALIZE_WHITESPACE
        {'t': 0.0, 'u': 5.0, 'y': 0.25, 'k': 0, 't_read': 0.001, 'jitter': 0.001,
         'lateness': 0.0, 'r': 6.0}
        """
        return {
            "t": self.t,
            "u": self.u,
            "y": self.y,
            "k": self.k,
            "t_read": self.t_read,
            "jitter": self.jitter,
            "lateness": self.lateness,
            **self.extra,
        }

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary with ``kind`` first (``extra`` as an object).

        Examples
        --------
        >>> SampleEvent(3, 0, 0.0, 0.001, 5.0, 0.25, 0.001, 0.0).to_dict()["kind"]
        'sample'
        """
        return {
            "kind": self.kind,
            "seq": self.seq,
            "k": self.k,
            "t": self.t,
            "t_read": self.t_read,
            "u": self.u,
            "y": self.y,
            "jitter": self.jitter,
            "lateness": self.lateness,
            "extra": {name: finite_or_none(v) for name, v in self.extra.items()},
        }


@dataclass(frozen=True, slots=True)
class EstimateEvent:
    """An identifier produced an estimate.

    Attributes
    ----------
    seq : int
        Event number within the run.
    k : int
        Index of the sample whose update produced it (the last sample at END).
    method : str
        The name the identifier was given in the run (``"wlsm"``...).
    estimate : SupportsToDict
        The identifier's estimate object.
    final : bool
        ``True`` for the estimate computed at END (``finish()``).
    """

    kind: ClassVar[str] = "estimate"
    seq: int
    k: int
    method: str
    estimate: SupportsToDict
    final: bool

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary with ``kind`` first."""
        return {
            "kind": self.kind,
            "seq": self.seq,
            "k": self.k,
            "method": self.method,
            "final": self.final,
            "estimate": self.estimate.to_dict(),
        }


@dataclass(frozen=True, slots=True)
class StateEvent:
    """The run changed state.

    Attributes
    ----------
    seq : int
        Event number within the run.
    state : RunState
        The new state.
    previous : RunState
        The state left.
    reason : str or None
        For terminal states, the end reason's value (``"completed"``,
        ``"rig_fault"``...); otherwise ``None``.
    message : str
        One human-readable line (empty when there is nothing to say).
    """

    kind: ClassVar[str] = "state"
    seq: int
    state: RunState
    previous: RunState
    reason: str | None = None
    message: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary with ``kind`` first.

        Examples
        --------
        >>> StateEvent(0, RunState.RUNNING, RunState.IDLE).to_dict()
        {'kind': 'state', 'seq': 0, 'state': 'running', 'previous': 'idle',
         'reason': None, 'message': ''}
        """
        return {
            "kind": self.kind,
            "seq": self.seq,
            "state": self.state.value,
            "previous": self.previous.value,
            "reason": self.reason,
            "message": self.message,
        }


@dataclass(frozen=True, slots=True)
class FaultEvent:
    """Something went wrong.

    Attributes
    ----------
    seq : int
        Event number within the run.
    k : int
        Index of the sample being taken (or about to be) when it happened.
    source : str
        ``"rig"``, ``"interlock"``, ``"watchdog"``, ``"identifier"``,
        ``"recorder"`` or ``"subscriber"``.
    message : str
        One line saying what happened.
    fatal : bool
        ``True`` if the run stops because of it; ``False`` when only one part
        stopped (an identifier that could not estimate; the others go on).
    """

    kind: ClassVar[str] = "fault"
    seq: int
    k: int
    source: str
    message: str
    fatal: bool = True

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary with ``kind`` first."""
        return {
            "kind": self.kind,
            "seq": self.seq,
            "k": self.k,
            "source": self.source,
            "message": self.message,
            "fatal": self.fatal,
        }


Event = SampleEvent | EstimateEvent | StateEvent | FaultEvent
"""Any event a run publishes."""
