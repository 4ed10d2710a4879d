"""A remote run's identification, done by the lab on the samples its host sends.

The host runs the experiment (sampling, input, interlocks); the lab feeds the
run's online identifiers — built by the same ``plan_run`` as an in-process
run's — with each sample as it is stored, in ``k`` order, and publishes
their estimates to the live stream as the runner would
(:class:`~thermolab.runner.EstimateEvent`). A sample sent again after a link
loss is already counted and is skipped, so the estimates are the ones an
in-process run of the same samples gives. At the end each method's result,
with the paper's figures (:func:`~thermolab.lab.runs.statistics.method_statistics`),
is what the run stores.

A run that identifies another pair than the rig's standard one (a kit's heater
2 and sensor 2, :mod:`thermolab.runner.pair`) is fed that pair's columns of
each sample, as the in-process runner feeds them.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator, Mapping
from typing import Any

from thermolab.errors import ThermoLabError
from thermolab.ident.online import OnlineIdentifier
from thermolab.lab.runs.ending import Record, method_results
from thermolab.lab.runs.export import RunExport
from thermolab.runner import EstimateEvent
from thermolab.runner.pair import IOPair
from thermolab.runner.results import MethodTrack

__all__ = ["RemoteIdentification"]

log = logging.getLogger(__name__)


class RemoteIdentification:
    """The online identifiers of one remote run, fed in sample order.

    Parameters
    ----------
    identifiers : dict
        Method name -> online identifier (``plan_run(...).identifiers``).
    units : (str, str), optional
        The pair's input and output units, which the stored results speak of.
    pair : IOPair, optional
        The pair the run identifies (default the standard ``u`` → ``y``).
    """

    def __init__(
        self,
        identifiers: dict[str, OnlineIdentifier],
        units: tuple[str, str] | None = None,
        pair: IOPair | None = None,
    ) -> None:
        self._identifiers = identifiers
        self._units = units
        self.pair = IOPair() if pair is None else pair
        self._tracks = {name: MethodTrack() for name in identifiers}
        self._errors: dict[str, str] = {}
        self._final: dict[str, Any] = {}
        self._finished = False
        self.next_k = 0

    def feed(
        self, k: int, u: float, y: float, extra: Mapping[str, float | None] | None = None
    ) -> list[EstimateEvent]:
        """Give sample ``k`` (its pair's columns) to every method; return their estimates
        (none for a repeat). ``extra``: the sample's further channels (JSON's null: NaN)."""
        return self._feed_pair(k, *self._columns(u, y, extra))

    def _feed_pair(self, k: int, u: float, y: float) -> list[EstimateEvent]:
        if k != self.next_k or self._finished:
            return []  # a resend of a sample already counted
        self.next_k = k + 1
        events = []
        for name, ident in self._identifiers.items():
            if name in self._errors:
                continue
            try:
                estimate = ident.update(u, y)
            except (ThermoLabError, ArithmeticError, ValueError) as exc:
                self._errors[name] = f"{name}: {exc}"  # that method stops; the run goes on
                continue
            if estimate is not None:
                self._tracks[name].add(k, estimate)
                events.append(EstimateEvent(k, k, name, estimate, False))
        return events

    def feed_stored(self, export: RunExport, run_id: int) -> None:
        """Feed the run's stored samples, in order (a run the lab identifies after a restart)."""
        for k, _, u, y in self._stored(export, run_id):
            self._feed_pair(k, u, y)

    def stored_record(self, export: RunExport, run_id: int, dt: float) -> Record:
        """The run's stored samples (all of them by its end: the host sends its outbox in
        order), the pair's columns, as the verdict on its models reads them."""
        rows = list(self._stored(export, run_id))
        t, u, y = ([row[i] for row in rows] for i in (1, 2, 3))
        return (t, u, y, dt)

    def _stored(self, export: RunExport, run_id: int) -> Iterator[tuple[int, float, float, float]]:
        """``(k, t, input, output)`` of the run's stored samples, the pair's columns."""
        if self.pair.standard:  # no further channel read: u and y are the pair
            yield from export.samples(run_id)
            return
        after = None
        while page := export.sample_page_with_extra(run_id, after, 2000):
            for k, t, u, y, extra in page:
                yield (k, t, *self._columns(u, y, extra))
            after = page[-1][0]

    def _columns(
        self, u: float, y: float, extra: Mapping[str, float | None] | None
    ) -> tuple[float, float]:
        """The pair's input and output in a sample (``extra``: its further channels)."""
        if self.pair.standard:
            return u, y
        further = {n: math.nan if v is None else v for n, v in (extra or {}).items()}
        return self.pair.columns(u, y, _Columns(further))

    def finish(self) -> list[EstimateEvent]:
        """END: every method's final estimate (SRM and LSM give theirs only now)."""
        if self._finished:
            return []
        self._finished = True
        k = max(self.next_k - 1, 0)
        events = []
        for name, ident in self._identifiers.items():
            if name in self._errors:
                continue
            try:
                estimate = ident.finish()
            except (ThermoLabError, ArithmeticError, ValueError) as exc:
                # ArithmeticError: a method's arithmetic on an odd record (the step
                # method's used to overflow on a short ENDed run); the end is stored anyway.
                log.warning("%s could not finish: %r", name, exc)
                self._errors[name] = f"{name}: {exc}"
                continue
            self._final[name] = estimate
            if estimate is not None:
                events.append(EstimateEvent(k, k, name, estimate, True))
        return events

    def results(
        self, run_id: int, record: Record | None = None
    ) -> dict[str, tuple[dict[str, Any], dict[str, Any]]]:
        """Each method's ``(settings, result)`` as the run stores them, with its figures
        (:func:`~thermolab.lab.runs.ending.method_results`, as an in-process run's),
        each final model judged on the run's stored ``record`` where it is given."""
        methods = {
            name: self._tracks[name].result(name, self._final.get(name), self._errors.get(name))
            for name in self._identifiers
        }
        return method_results(run_id, methods, self._identifiers, self._units, record)


class _Columns(dict[str, float]):
    """A sample's further channels, a channel it lacks read as NaN (a sample sent without
    it): a method refuses a NaN sample and stops with the reason, as in-process."""

    def __missing__(self, name: str) -> float:
        return math.nan
