"""Who is watching which rig.

A user watches a rig while they hold a live connection to it (the WebSocket
counts connections) or have made a request for it within the client timeout
(a page that polls). Presence is kept in memory: it describes the connections
of this server process and means nothing after a restart.
"""

from __future__ import annotations

import itertools
import threading
from dataclasses import dataclass
from datetime import datetime, timedelta

from thermolab.lab.clock import LabClock

__all__ = ["Presence", "Watcher"]


@dataclass(frozen=True, slots=True)
class Watcher:
    """One user watching a rig.

    Attributes
    ----------
    username : str
    connections : int
        Live connections (WebSockets) the user has open to the rig.
    last_seen : datetime
        Last request or message from the user about the rig.
    """

    username: str
    connections: int
    last_seen: datetime


class Presence:
    """Counts watchers per rig.

    Parameters
    ----------
    clock : LabClock
    timeout : float
        Seconds after the last request at which a user without a live
        connection stops counting as a watcher.

    Examples
    --------
    >>> from thermolab.lab.clock import ManualClock
    >>> clock = ManualClock()
    >>> presence = Presence(clock, timeout=15)
    >>> handle = presence.connect("twin", "alice")
    >>> presence.touch("twin", "bob")
    >>> [w.username for w in presence.watchers("twin")]
    ['alice', 'bob']
    >>> clock.advance(20)
    >>> [w.username for w in presence.watchers("twin")]
    ['alice']
    >>> presence.disconnect(handle)  # counts for another timeout, like a request
    >>> presence.count("twin")
    1
    >>> clock.advance(15)
    >>> presence.count("twin")
    0
    """

    def __init__(self, clock: LabClock, *, timeout: float) -> None:
        self._clock = clock
        self._timeout = timedelta(seconds=timeout)
        self._seen: dict[tuple[str, str], datetime] = {}
        self._connections: dict[int, tuple[str, str]] = {}
        self._handles = itertools.count(1)
        self._lock = threading.Lock()

    def touch(self, rig_id: str, username: str) -> None:
        """Note a request from ``username`` about ``rig_id``."""
        now = self._clock.now()
        with self._lock:
            self._seen[(rig_id, username)] = now

    def connect(self, rig_id: str, username: str) -> int:
        """Note a live connection; return a handle for :meth:`disconnect`."""
        now = self._clock.now()
        with self._lock:
            handle = next(self._handles)
            self._connections[handle] = (rig_id, username)
            self._seen[(rig_id, username)] = now
            return handle

    def disconnect(self, handle: int) -> None:
        """Forget a live connection (unknown handles are ignored)."""
        now = self._clock.now()
        with self._lock:
            key = self._connections.pop(handle, None)
            if key is not None:
                self._seen[key] = now

    def watchers(self, rig_id: str) -> list[Watcher]:
        """Return the users watching ``rig_id``, by user name."""
        now = self._clock.now()
        with self._lock:
            counts: dict[str, int] = {}
            for rig, user in self._connections.values():
                if rig == rig_id:
                    counts[user] = counts.get(user, 0) + 1
            result = []
            for (rig, user), seen in list(self._seen.items()):
                if rig != rig_id:
                    continue
                live = counts.get(user, 0)
                if live == 0 and now - seen >= self._timeout:
                    del self._seen[(rig, user)]
                    continue
                result.append(Watcher(user, live, seen))
            return sorted(result, key=lambda w: w.username)

    def count(self, rig_id: str) -> int:
        """Return how many users watch ``rig_id``."""
        return len(self.watchers(rig_id))
