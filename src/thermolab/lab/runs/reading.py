"""Reading runs back for the routes: one run, the listings, the samples and the exports.

:class:`RunReading` is the reading half of :class:`~thermolab.lab.runs.service.RunService`
(its base class): who may read which run (:meth:`~.store.RunStore.owned_run`),
the runs newest first, a run's samples by channel (:mod:`.export`) and its
JSON export. How one run reads now — stored, or as it is while it runs — is the
service's (:meth:`record`), which knows the runs going.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator
from typing import Any

from thermolab.jsonsafe import json_safe
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.models import Run
from thermolab.lab.runs.export import RunExport, StoredSample
from thermolab.lab.runs.store import RunRecord, RunStore
from thermolab.records import ChannelSpec

__all__ = ["RunReading"]


class RunReading(ABC):
    """The runs read back, checked against who asks (a student's own; any for a teacher)."""

    _store: RunStore
    _export: RunExport

    @abstractmethod
    def record(self, run_id: int) -> RunRecord:
        """Return one run, whoever owns it (as it is now, if it is going)."""

    @abstractmethod
    def _record(self, run: Run, stored: dict[str, Any] | None) -> RunRecord:
        """Return a run's row as a record (``stored``: its methods' stored results)."""

    def get(self, run_id: int, who: Principal) -> RunRecord:
        """Return one run (a student's own or one that is running; any for a teacher).

        Raises
        ------
        NotFoundError
            If there is no such run.
        AccessDeniedError
            If it belongs to another user and ``who`` is a student.
        """
        self._store.owned_run(run_id, who)
        return self.record(run_id)

    def list(
        self,
        who: Principal,
        rig_id: str | None = None,
        limit: int = 200,
        *,
        user: str | None = None,
    ) -> list[RunRecord]:
        """Return runs, newest first: a student's own, or everyone's for a teacher.

        ``user`` narrows it to one user: anyone for a teacher, only themselves
        for a student.

        Raises
        ------
        AccessDeniedError
            If a student asks for another user's runs.
        NotFoundError
            If a teacher names a user who does not exist.
        InvalidParameterError
            If ``user`` is not a valid user name.
        """
        return [self._record(run, None) for run in self._store.rows(who, rig_id, limit, user)]

    def samples(self, run_id: int, who: Principal) -> Iterator[StoredSample]:
        """Yield ``(k, t, u, y)`` of every stored sample of a run, in order (checked as get)."""
        self._store.owned_run(run_id, who)
        return self._export.samples(run_id)

    def record_rows(
        self, run_id: int, who: Principal
    ) -> tuple[tuple[ChannelSpec, ...], Iterator[tuple[float, ...]]]:
        """Return a run's channels and its samples' values of them (checked as get)."""
        self._store.owned_run(run_id, who)
        channels = self._export.channels(run_id)
        return channels, self._export.channel_rows(run_id, channels)

    def export(self, run_id: int, who: Principal) -> dict[str, Any]:
        """Return a run with its samples and every method's stored result (JSON-ready)."""
        record = self.get(run_id, who)
        _, methods = self._store.read(run_id)
        # The samples by channel name, with the channels' units (thermolab.records).
        exported: dict[str, Any] = json_safe(
            {"run": record, **self._export.record(run_id), "methods": methods}
        )
        return exported
