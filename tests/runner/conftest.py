"""Shared pieces for the runner's tests: twins with hooks (box and kit), fake identifiers."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import pytest

from thermolab.rigs import KitTwinRig, Reading, VirtualClock
from thermolab.rigs.base import BaseRig
from thermolab.rigs.twin import TwinRig


class _ReadingHooks(BaseRig):
    """Calls ``hooks[n]()`` just before the rig's ``n``-th reading (0-based).

    The hook runs inside the sampling loop, at a known sample, so a test can
    act "mid-run" (change the set point, request END, stall the clock, read
    the CSV) deterministically on a virtual clock. Mixed in before a rig class.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.hooks: dict[int, Callable[[], object]] = {}
        self.reads = 0

    def _read_output(self) -> Reading:
        hook = self.hooks.get(self.reads)
        self.reads += 1
        if hook is not None:
            hook()
        return super()._read_output()


class HookedTwin(_ReadingHooks, TwinRig):
    """The paper's twin, with reading hooks (:class:`_ReadingHooks`)."""


class HookedKit(_ReadingHooks, KitTwinRig):
    """The kit's twin, with reading hooks (:class:`_ReadingHooks`)."""


@dataclass(frozen=True)
class FakeEstimate:
    """A stand-in estimate: the running mean of the outputs seen."""

    n: int
    mean: float

    def to_dict(self) -> dict[str, Any]:
        return {"n": self.n, "mean": self.mean}


class MeanIdentifier:
    """An online 'identifier' with a known answer: the mean of y, every ``every`` samples."""

    def __init__(self, every: int = 1) -> None:
        self.every = every
        self.n = 0
        self.total = 0.0
        self.finished = False

    def update(self, u: float, y: float) -> FakeEstimate | None:
        self.n += 1
        self.total += y
        if self.n % self.every:
            return None
        return FakeEstimate(self.n, self.total / self.n)

    def finish(self) -> FakeEstimate | None:
        self.finished = True
        return FakeEstimate(self.n, self.total / self.n) if self.n else None

    def to_dict(self) -> dict[str, Any]:
        return {"method": "mean", "every": self.every}


@pytest.fixture
def clock() -> VirtualClock:
    return VirtualClock()


@pytest.fixture
def twin(clock: VirtualClock) -> Iterator[HookedTwin]:
    # The paper's twin, noise-free; a 10 V input settles at 1.4009 V (limit 5 V).
    with HookedTwin("paper", clock=clock, seed=0) as rig:
        yield rig
