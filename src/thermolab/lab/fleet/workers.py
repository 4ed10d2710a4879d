"""Several web workers on one database and one bus: who owns the rigs, what travels.

With a broker (``thermolab serve --broker redis://...``), any number of
workers share one PostgreSQL database. The first to start takes the
database's lease (:mod:`~thermolab.lab.fleet.lease`) as before and becomes the
**owner**: it opens the rig devices, runs the runs, the sweep and start-up
recovery, exactly as a lone server. Every later worker, finding the lease
held by an owner that announces itself on the bus, starts as a **follower**
(:class:`FollowerLab`): no devices, no start-up recovery, no sweep. Without a
broker the held lease still refuses the second process (fail closed).
A **standby** follower (``--standby``, or any follower when every rig is on
a rig host) watches the owner's lease and, when it lapses (the owner killed),
takes it and owns the rigs from then on without a restart
(:meth:`FollowerLab.promote`; of several standbys the lease lets one win):
same control sessions and queue, its channels numbering on from the last
``seq`` heard, its address announced, so the other followers forward to it.

What crosses the bus (:class:`Fleet`):

* ``live``: the owner's replayable live messages (samples, estimates, runs),
  numbered by the owner (one ``seq`` space for every worker), so a client
  that moves to another worker resumes with ``since`` and misses nothing;
* ``access``: "rig X changed" — each worker renders its own clients' access
  messages from the database;
* ``owner``: once a second, the owner's address and each rig's ``seq``.

A follower serves logins, accounts, courses, pages and — the bulk of the
load — live sockets itself; every request about rigs and runs
(``/api/rigs``, ``/api/runs``, ``/api/control``) is forwarded to the owner
(:mod:`~thermolab.lab.http.forward`; held up to :data:`OWNER_WAIT` while
no owner answers, e.g. during a takeover), so one process decides every
turn, queue place and time limit, under the database's row locks as before.
Once rig hosts dial in (``thermolab agent``), the owner's part is the
agent's: :attr:`Fleet.owner_url` is the one place a follower asks where
rig commands go.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Literal

from thermolab.lab.config import LabConfig
from thermolab.lab.config.rig_kinds import PublishedRig
from thermolab.lab.fleet.bus import Bus, open_bus
from thermolab.lab.fleet.follower import FollowerLab
from thermolab.lab.fleet.lease import LEASE_TTL, LeaseHeldError
from thermolab.lab.fleet.shared_limits import (
    LiveSocketCounts,
    SharedInitiationRate,
    SharedLiveSocketCounts,
    SharedLoginThrottle,
)
from thermolab.lab.fleet.worker_hashes import figures_client
from thermolab.lab.live.shared_presence import SharedPresence
from thermolab.lab.outcomes import StartupReport
from thermolab.lab.rigs.opener import RigOpener
from thermolab.lab.service import Lab

if TYPE_CHECKING:
    from thermolab.lab.live.fanout import LiveFanout

__all__ = ["ANNOUNCE_INTERVAL", "OWNER_WAIT", "Fleet", "FollowerLab", "Role", "start_worker"]

log = logging.getLogger(__name__)

ANNOUNCE_INTERVAL = 1.0
"""Seconds between the owner's announcements on the bus."""
OWNER_SILENCE = 5.0
"""A follower that has not heard the owner for this long knows none (:attr:`Fleet.owner_url`)."""
OWNER_WAIT = LEASE_TTL.total_seconds() + 2 * ANNOUNCE_INTERVAL
"""Seconds a follower holds a rig request while no owner answers: a takeover's longest gap.

The dead owner's lease runs out at most ``LEASE_TTL`` after its last renewal
(at once when it was a process of the standby's host); a standby asks once an
``ANNOUNCE_INTERVAL`` whether it has; once it owns, its first announcement goes
out at once — one more interval allowed for opening the devices, recovering
and the bus. A follower that hears no owner answer within this answers 503.
"""

Role = Literal["alone", "owner", "follower"]


class Fleet:
    """This worker's part in a fleet of workers joined by a bus.

    Parameters
    ----------
    bus : Bus
    role : {"alone", "owner", "follower"}
    url : str, optional
        Where this worker is reached (an owner announces it to followers; a
        standby follower, once promoted).
    live_sockets : LiveSocketCounts, optional
        The live sockets of every worker (:mod:`~thermolab.lab.fleet.shared_limits`),
        which the live stream's limits count; closed with the fleet.
    watchers : SharedPresence, optional
        Who watches each rig on every worker (:mod:`~thermolab.lab.live.shared_presence`);
        closed with the fleet.
    """

    def __init__(
        self,
        bus: Bus,
        role: Role,
        *,
        url: str | None = None,
        live_sockets: LiveSocketCounts | None = None,
        watchers: SharedPresence | None = None,
    ) -> None:
        self.bus = bus
        self.role: Role = role
        self.url = url
        self.live_sockets = live_sockets
        self.watchers = watchers
        self._standby: threading.Thread | None = None
        self._owner: tuple[str, float] | None = None  # (address, monotonic time heard)
        #: How many owner announcements this follower has heard (a live owner adds one a second).
        self.announcements = 0
        self._heard = threading.Event()
        self._seqs: dict[str, int] = {}
        self._stop = threading.Event()
        self._announcer: threading.Thread | None = None
        self._fanout: LiveFanout | None = None
        self._access: Callable[[str], None] | None = None
        self._lab: Lab | None = None
        self._owner_news: dict[str, Any] = {}
        self._owner_listeners: list[Callable[[], None]] = []
        if role == "follower":
            bus.subscribe("owner", self._heard_owner)

    @property
    def owner_url(self) -> str | None:
        """The owner's address, if it was heard recently (followers); ``None`` otherwise."""
        if self.role != "follower":
            return None
        owner = self._owner
        if owner is None or time.monotonic() - owner[1] > OWNER_SILENCE:
            return None
        return owner[0]

    def on_owner(self, listener: Callable[[], None]) -> None:
        """Call ``listener()`` each time an owner is heard, or this worker becomes the owner.

        It is called from the bus's thread: it must only hand the news on
        (the forwarding wakes the requests waiting for an owner).
        """
        self._owner_listeners.append(listener)

    def _tell_owner_listeners(self) -> None:
        for listener in self._owner_listeners:
            listener()

    def wait_for_owner(self, timeout: float) -> bool:
        """Wait until the owner has announced itself; ``False`` if it did not in time."""
        return self._heard.wait(timeout)

    def join(
        self, fanout: LiveFanout, access_changed: Callable[[str], None], lab: Lab | None = None
    ) -> None:
        """Connect this worker's live stream to the others' (call once the loop is bound).

        ``lab`` is this worker's: the owner announces what its rigs accept; a
        follower (a :class:`FollowerLab`) takes it.
        """
        self._fanout = fanout
        self._access = access_changed
        self._lab = lab
        if self.role == "owner":
            self._own()
        elif self.role == "follower":
            self._adopt_published()
            for rig_id, seq in self._seqs.items():
                heard = fanout.channels.get(rig_id)
                if heard is not None:
                    heard.follow(seq)
            self.bus.subscribe("live", self._heard_live)
            self.bus.subscribe("access", self._heard_access)
            if isinstance(lab, FollowerLab) and lab.standby:
                self._standby = threading.Thread(
                    target=self._stand_by, args=(lab,), name="fleet-standby", daemon=True
                )
                self._standby.start()

    def access_changed(self, rig_id: str) -> None:
        """Tell the other workers that a rig's access changed (the owner's lab calls it)."""
        if self.role == "owner":
            self.bus.publish("access", rig_id.encode())

    def run_changed(self, rig_id: str, event: str, record: Any) -> None:
        """Nothing: a run's messages travel on the live stream (``relay``)."""

    def run_event(self, rig_id: str, run_id: int, event: Any) -> None:
        """Nothing: as :meth:`run_changed`."""

    def reading(
        self,
        rig_id: str,
        u: float | None,
        y: float,
        at: Any,
        channels: Mapping[str, float | None] | None = None,
    ) -> None:
        """Nothing: as :meth:`run_changed`."""

    def close(self) -> None:
        """Stop announcing (or standing by) and leave the bus."""
        self._stop.set()
        if self._standby is not None:
            self._standby.join(timeout=30)
        if self._announcer is not None:
            self._announcer.join(timeout=5)
        if self.live_sockets is not None:
            self.live_sockets.close()
        if self.watchers is not None:
            self.watchers.close()
        self.bus.close()

    # -- the owner's side --------------------------------------------------------------------

    def _own(self) -> None:
        # The live stream goes on from each channel's seq (the old owner's last, on a
        # promoted follower): one seq space across the takeover, no reset for any client.
        fanout = self._fanout
        for channel in () if fanout is None else fanout.channels.values():
            channel.relay = self._relay
        self._announcer = threading.Thread(
            target=self._announce_forever, name="fleet-announce", daemon=True
        )
        self._announcer.start()

    def _promoted(self) -> None:
        self.role = "owner"
        self._owner = None
        self._own()
        self._tell_owner_listeners()

    def _stand_by(self, lab: FollowerLab) -> None:
        # A standby watches the owner's lease; when it lapses, one standby takes it
        # (FollowerLab.promote) and owns the rigs from then on, in this process.
        while not self._stop.wait(ANNOUNCE_INTERVAL):
            try:
                if not lab.promote(self._promoted):
                    continue
            except Exception:  # the database unreachable: ask again
                log.exception("a standby worker could not take over the rigs")
                continue
            log.warning("this worker now owns the rigs (%s)", self.url)
            return

    def _relay(self, rig_id: str, text: str) -> None:
        self.bus.publish("live", f"{rig_id}\n{text}".encode())

    def _announce_forever(self) -> None:
        while not self._stop.is_set():
            lease = None if self._lab is None else self._lab.lease
            if lease is not None and lease.lost:
                # Stalled past the lease's expiry, this worker was replaced (a standby took
                # over): two owners must not drive one rig. Stop the way a server stops
                # (runs ended, actuators safe); restarted, it follows the new owner.
                log.critical("another worker took over the rigs' lease: this worker stops")
                os.kill(os.getpid(), signal.SIGTERM)
                return
            fanout = self._fanout
            seqs = {} if fanout is None else {r: c.seq for r, c in fanout.channels.items()}
            lab = self._lab
            published = (
                {}
                if lab is None
                else {r.id: dataclasses.asdict(lab.hub.published(r.id)) for r in lab.config.rigs}
            )
            news = {"url": self.url, "seqs": seqs, "published": published}
            self.bus.publish("owner", json.dumps(news).encode())
            self._stop.wait(ANNOUNCE_INTERVAL)

    # -- a follower's side -------------------------------------------------------------------

    def _heard_owner(self, data: bytes) -> None:
        if self.role != "follower":
            return  # its own announcement, heard back
        news: dict[str, Any] = json.loads(data)
        url = news.get("url")
        if isinstance(url, str):
            self._owner = (url, time.monotonic())
        self.announcements += 1
        self._owner_news = news
        self._adopt_published()
        seqs = news.get("seqs") or {}
        fanout = self._fanout
        for rig_id, seq in seqs.items():
            self._seqs.setdefault(rig_id, int(seq))
            channel = None if fanout is None else fanout.channels.get(rig_id)
            if channel is not None:
                channel.follow(int(seq))
        self._heard.set()
        self._tell_owner_listeners()

    def _adopt_published(self) -> None:
        lab = self._lab
        if isinstance(lab, FollowerLab):
            for rig_id, fields in (self._owner_news.get("published") or {}).items():
                lab.adopt_published(rig_id, PublishedRig.from_dict(fields))

    def _heard_live(self, data: bytes) -> None:
        if self.role != "follower":
            return  # promoted: its own messages, heard back
        rig_id, _, text = data.decode().partition("\n")
        fanout = self._fanout
        channel = None if fanout is None else fanout.channels.get(rig_id)
        if channel is not None:
            channel.publish_numbered(json.loads(text), text)

    def _heard_access(self, data: bytes) -> None:
        if self._access is not None and self.role == "follower":
            self._access(data.decode())


def start_worker(
    config: LabConfig,
    *,
    opener: RigOpener | None,
    broker: str | None,
    url: str,
    standby: bool = False,
) -> tuple[Lab, Fleet | None, StartupReport]:
    """Start this process's lab: alone (no broker), the owner, or a follower.

    A follower stands by to take the rigs over (:meth:`FollowerLab.promote`)
    when ``standby`` (``--standby``: this machine can open the lab's devices)
    or when every rig of the lab is on a rig host (``agent = true``: the hosts
    dial in to whichever worker owns).

    Raises
    ------
    LeaseHeldError
        Another server holds the database and there is no broker, or that
        server does not announce itself on the broker (fail closed).
    BusError
        The broker cannot be reached.
    """
    # The lab's topics and keys are its database's: labs on one broker do not hear each other.
    lab_key = hashlib.sha256(config.database.encode()).hexdigest()[:12]
    prefix = f"thermolab.{lab_key}."
    bus = open_bus(broker, prefix=prefix) if broker is not None else None
    # With a broker, the login throttles, the live-socket limits and the watchers are lab-wide.
    figures = figures_client(broker) if broker is not None else None
    lab = Lab(config, opener=opener, exclusive=True)
    if figures is not None:
        lab.throttle = SharedLoginThrottle.like(lab.throttle, figures, prefix)
        lab.lti.launches.initiations = SharedInitiationRate.like(
            lab.lti.launches.initiations, figures, prefix
        )
    try:
        report = lab.start()
    except LeaseHeldError as held:
        lab.close()
        if bus is None or figures is None:
            raise
        fleet = Fleet(bus, "follower", url=url)
        if not fleet.wait_for_owner(3 * ANNOUNCE_INTERVAL + 2.0):
            bus.close()
            raise LeaseHeldError(
                f"{held} (the server holding it does not announce itself on the broker "
                f"{broker}: start it with the same --broker)"
            ) from None
        fleet.live_sockets = SharedLiveSocketCounts(figures, prefix)
        remote_only = all(rig.agent for rig in config.rigs)
        follower = FollowerLab(config, standby=standby or remote_only, opener=opener)
        follower.throttle = SharedLoginThrottle.like(follower.throttle, figures, prefix)
        follower.lti.launches.initiations = SharedInitiationRate.like(
            follower.lti.launches.initiations, figures, prefix
        )
        fleet.watchers = SharedPresence(follower.presence, figures, prefix)
        try:
            return follower, fleet, follower.start()
        except BaseException:
            follower.close()
            fleet.close()
            raise
    except BaseException:
        lab.close()
        if bus is not None:
            bus.close()
        raise
    if bus is None or figures is None:
        return lab, None, report
    live_sockets = SharedLiveSocketCounts(figures, prefix)
    watchers = SharedPresence(lab.presence, figures, prefix)
    fleet = Fleet(bus, "owner", url=url, live_sockets=live_sockets, watchers=watchers)
    return lab, fleet, report
