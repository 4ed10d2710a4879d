"""A follower worker's lab (:class:`FollowerLab`) and its promotion to owner.

A follower (:mod:`~thermolab.lab.fleet.workers`) serves but owns no rig: no
devices, no start-up recovery, no sweep; the owner, another process, does
what touches a rig or a run's limits. A **standby** follower
(``thermolab serve --broker ... --standby``, or any follower of a lab whose
rigs are all on rig hosts) may become the owner without a restart when the
owner's lease lapses (:meth:`FollowerLab.promote`): it takes the lease (of
several standbys, one wins: the lease row's lock), opens the devices, and
recovers as a restarted owner would, except that control sessions and queue
places stay as the database has them — the same controller goes on (their
heartbeats count from the takeover: the followers held them meanwhile, or
refused those the dead owner took unanswered):

* a run that was going on an in-process rig of the dead owner is marked
  interrupted (its device is opened anew, at its safe input);
* a run going on a rig host is adopted (:meth:`RemoteRuns.adopt`, its
  identifiers built again): the host keeps sampling through its grace and,
  once it dials the new owner, its samples and its end are stored as before.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from datetime import timedelta
from typing import Any

from sqlalchemy import select, update

from thermolab.lab.access.queries import SERVER_STOPPED
from thermolab.lab.config import LabConfig
from thermolab.lab.config.rig_kinds import PublishedRig
from thermolab.lab.db.models import ControlSession, QueueEntry, Run, RunStatus
from thermolab.lab.fleet.lease import LeaseHeldError
from thermolab.lab.outcomes import StartupReport
from thermolab.lab.service import Lab

__all__ = ["FollowerLab"]

log = logging.getLogger(__name__)


class FollowerLab(Lab):
    """A lab that serves but owns no rig until, a standby, it is promoted.

    Parameters
    ----------
    config : LabConfig
    standby : bool
        May become the owner when the owner's lease lapses (:meth:`promote`).
    **options
        As :class:`~thermolab.lab.service.Lab`'s (the opener is used once promoted).
    """

    def __init__(self, config: LabConfig, *, standby: bool = False, **options: Any) -> None:
        super().__init__(config, exclusive=True, **options)
        self.standby = standby
        self.owner = False
        # The run going on a rig is the owner's (in its memory); here the store says which:
        # a live client's hello and the replay of what it missed read it.
        self._own_running = self.runs.running
        self.runs.running = self._running_in_store  # type: ignore[method-assign]
        # What each rig accepts (its range, whether a device is attached) is the owner's:
        # it announces it, and a follower's views say the same.
        self._published: dict[str, PublishedRig] = {}
        self._configured = self.hub.published
        self.hub.published = self._published_by_owner  # type: ignore[method-assign]

    def adopt_published(self, rig_id: str, published: PublishedRig) -> None:
        """Take what the owner announced that rig ``rig_id`` accepts."""
        self._published[rig_id] = published

    def _published_by_owner(self, rig_id: str) -> PublishedRig:
        published = self._published.get(rig_id)
        return published if published is not None else self._configured(rig_id)

    def _running_in_store(self, rig_id: str) -> int | None:
        with self.db.read() as session:
            run_id: int | None = session.scalar(
                select(Run.id).where(Run.rig_id == rig_id, Run.status == RunStatus.RUNNING.value)
            )
        return run_id

    def start(self) -> StartupReport:
        """Migrate (a no-op when the owner did) and report; runs and turns are the owner's."""
        if self._report is None:
            self.db.upgrade()
            self._report = StartupReport(teachers=self.users.count_teachers(), faults={})
        return self._report

    def end_token_turns(self, token_ids: frozenset[int]) -> None:
        """Only once promoted: the owner's devices would not hear of a turn ended here.

        Until then a revoked token's turn ends at the owner, by the client
        timeout (the token's heartbeats are refused).
        """
        if self.owner:
            super().end_token_turns(token_ids)

    def sweep(self) -> list[str]:
        """Nothing until promoted (limits and hand-overs are the owner's); then the owner's."""
        return super().sweep() if self.owner else []

    def promote(self, owning: Callable[[], None] | None = None) -> bool:
        """Become the owner if the owner's lease has lapsed; ``True`` once this lab owns.

        Called about once a second by a standby's fleet. A lost race for the
        lease (another standby took it first) leaves this lab a follower.
        ``owning`` is called once this lab owns, before it tells its listeners
        of the runs the takeover ended (the fleet relays the live stream from then on).
        """
        if self.owner:
            return True
        lease = self.lease
        if not self.standby or lease is None or not lease.lapsed():
            return False
        try:
            lease.acquire()
        except LeaseHeldError:
            return False
        log.warning("the owner's lease lapsed: this worker takes over the rigs")
        with self._sweep_lock:
            self.runs.running = self._own_running  # type: ignore[method-assign]
            self.hub.published = self._configured  # type: ignore[method-assign]
            faults = self.hub.open_all()
            self.settings.load()
            interrupted, remote = self._recover()
            for rig_id, run_id, control in remote:
                self.remote_runs.adopt(rig_id, run_id, control)
            # The hosts were the dead owner's: each gets its run's grace to dial in here.
            self.agents.expect_hosts(self.clock.now() + timedelta(seconds=self.agents.grace))
            self.agents.check(self.clock.now())
            for rig in self.config.rigs:
                self._reconcile(rig.id)
            for rig_id, message in faults.items():
                self.access.report_fault(rig_id, message)
            self.owner = True
        if owning is not None:
            owning()
        for rig_id, run_id in interrupted:
            self._run_changed(rig_id, "ended", self.runs.record(run_id))
        return True

    def _recover(self) -> tuple[list[tuple[str, int]], list[tuple[str, int, int]]]:
        # The dead owner's runs: its in-process ones ended with it; its hosts' go on.
        interrupted: list[tuple[str, int]] = []
        remote: list[tuple[str, int, int]] = []
        now = self.clock.now()
        with self.db.write() as session:
            # While no one owned, followers held the heartbeats (some 503): the gap is the
            # lab's, not the students' — no turn or queue place ends for it.
            for kind, ended in (
                (ControlSession, ControlSession.ended_at),
                (QueueEntry, QueueEntry.left_at),
            ):
                session.execute(update(kind).where(ended.is_(None)).values(last_heartbeat_at=now))
            going = session.scalars(select(Run).where(Run.status == RunStatus.RUNNING.value))
            for run in going:
                if run.rig_id in self.remote_rigs and run.control_session_id is not None:
                    remote.append((run.rig_id, run.id, run.control_session_id))
                    continue
                run.status = RunStatus.INTERRUPTED.value
                run.ended_at = now
                run.end_reason = SERVER_STOPPED  # a restarted owner's words
                interrupted.append((run.rig_id, run.id))
        return interrupted, remote
