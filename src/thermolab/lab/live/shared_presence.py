"""Who watches which rig, lab-wide when workers share a Redis broker.

Each worker knows its own watchers exactly (:class:`~thermolab.lab.live.presence.Presence`:
its live sockets, the recent requests it served). Over a fleet (``docs/fleet.md``)
the rig's page must count everyone, wherever their socket landed:
:class:`SharedPresence` publishes this worker's watchers as its
:class:`~thermolab.lab.fleet.worker_hashes.WorkerHash` of kind ``watchers`` (one
field per rig: each watcher's name, live connections and last contact), and
reads the other live workers' once a second into memory, which the presence
merges with its own (rendering a rig never waits on Redis). A remote change
that alters who watches a rig is handed to the presence's listeners (the
live stream sends the access messages again). While Redis cannot be reached,
this worker's own watchers are all it counts, as a lone server's.
"""

from __future__ import annotations

import json
import logging
import threading
from datetime import UTC, datetime
from typing import Any

from thermolab.lab.fleet.worker_hashes import WorkerHash
from thermolab.lab.live.presence import Presence, Watcher

__all__ = ["SharedPresence"]

log = logging.getLogger(__name__)


class SharedPresence:
    """A worker's watchers published to Redis; the other workers' read back once a ``poll``.

    Parameters
    ----------
    presence : Presence
        This worker's: it is shared (:meth:`Presence.share`) until :meth:`close`.
    redis : redis.Redis
        The broker (:func:`~thermolab.lab.fleet.worker_hashes.figures_client`).
    prefix : str
        The lab's key prefix.
    refresh, ttl : float
        Seconds between writes with no change, and a write's lifetime.
    gap : float
        Least seconds between two writes (a lecture hall connecting at once is
        written a few times a second, not once per socket).
    poll : float
        Seconds between reads of the other workers' watchers.
    """

    def __init__(
        self,
        presence: Presence,
        redis: Any,
        prefix: str,
        *,
        refresh: float = 2.0,
        ttl: float = 6.0,
        gap: float = 0.25,
        poll: float = 1.0,
    ) -> None:
        self._presence = presence
        self._poll = poll
        self._others: dict[str, list[Watcher]] = {}
        self._seen_by_rig: dict[str, frozenset[str]] = {}  # who watched each rig at the last read
        self._stop = threading.Event()
        self.published = WorkerHash(
            redis, prefix, "watchers", self._fields, refresh=refresh, ttl=ttl, gap=gap
        )
        presence.share(self)
        self._reader = threading.Thread(
            target=self._read_forever, name="watchers-read", daemon=True
        )
        self._reader.start()

    def watchers(self, rig_id: str) -> list[Watcher]:
        """The other live workers' watchers of ``rig_id`` at the last read (a name may repeat)."""
        return self._others.get(rig_id, [])

    def changed(self) -> None:
        """This worker's watchers changed: publish them soon."""
        self.published.changed()

    def read(self) -> None:
        """Read the other workers' watchers now; tell the presence's listeners what changed."""
        found = self.published.others_whole()
        others: dict[str, list[Watcher]] = {}
        for whole in found or []:
            for name, value in whole.items():
                if name.startswith(b"r:"):
                    rig_id = name[2:].decode()
                    others.setdefault(rig_id, []).extend(_watchers(value))
        self._others = others  # one assignment: renderers see the old reading or the new
        for rig_id in set(others) | set(self._seen_by_rig):
            names = frozenset(w.username for w in self._presence.watchers(rig_id))
            if names != self._seen_by_rig.get(rig_id, frozenset()):
                if names:
                    self._seen_by_rig[rig_id] = names
                else:
                    self._seen_by_rig.pop(rig_id, None)
                self._presence.elsewhere_changed(rig_id)

    def halt(self) -> None:
        """Stop reading and writing, leaving the published watchers to expire (tests: a kill)."""
        self._stop.set()
        self._reader.join(timeout=5)
        self.published.halt()

    def close(self) -> None:
        """Stop; this worker's watchers are taken out of Redis at once, its presence is alone."""
        self._stop.set()
        self._reader.join(timeout=5)
        self.published.close()
        self._presence.share(None)

    def _fields(self) -> dict[str, str | int]:
        return {
            f"r:{rig_id}": json.dumps(
                [[w.username, w.connections, w.last_seen.timestamp()] for w in watchers]
            )
            for rig_id, watchers in self._presence.here().items()
        }

    def _read_forever(self) -> None:
        while not self._stop.wait(self._poll):
            try:
                self.read()
            except Exception:  # a bad reading must not stop the next ones
                log.exception("reading the other workers' watchers failed")


def _watchers(value: bytes) -> list[Watcher]:
    return [
        Watcher(str(name), int(connections), datetime.fromtimestamp(float(seen), tz=UTC))
        for name, connections, seen in json.loads(value)
    ]
