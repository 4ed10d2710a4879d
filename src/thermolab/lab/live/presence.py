"""Who is watching which rig.

A user watches a rig while they hold a live connection to it (the WebSocket
counts connections) or have made a request for it within the client timeout
(a page that polls). Presence is kept in memory: it describes the connections
of this server process and means nothing after a restart.

Workers of a fleet (``docs/fleet.md``) each know their own watchers exactly;
shared (:meth:`Presence.share`, :mod:`~thermolab.lab.live.shared_presence`), a
worker's watchers are its own merged with what the other live workers
published, one person counting once however many workers they are on.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Protocol

from thermolab.lab.clock import LabClock

__all__ = ["Elsewhere", "Presence", "Watcher"]


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


class Elsewhere(Protocol):
    """The watchers other workers hold (:class:`.shared_presence.SharedPresence`)."""

    def watchers(self, rig_id: str) -> list[Watcher]:
        """What the other live workers published for ``rig_id`` (from memory: never blocks)."""
        ...

    def changed(self) -> None:
        """This worker's watchers changed (publish them soon)."""
        ...


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
        self._elsewhere: Elsewhere | None = None
        self._listeners: list[Callable[[str], None]] = []

    def share(self, elsewhere: Elsewhere | None) -> None:
        """Count the watchers of ``elsewhere`` too, and tell it of this worker's changes."""
        self._elsewhere = elsewhere

    def on_elsewhere(self, listener: Callable[[str], None]) -> None:
        """Call ``listener(rig_id)`` when a rig's watchers changed on another worker.

        It is called from a thread of :meth:`share`'s ``elsewhere``: it must only
        hand the news on (the live stream schedules an access update).
        """
        self._listeners.append(listener)

    def elsewhere_changed(self, rig_id: str) -> None:
        """Tell the listeners that ``rig_id``'s watchers changed on another worker."""
        for listener in self._listeners:
            listener(rig_id)

    def touch(self, rig_id: str, username: str) -> None:
        """Note a request from ``username`` about ``rig_id``."""
        now = self._clock.now()
        with self._lock:
            old = self._seen.get((rig_id, username))
            self._seen[(rig_id, username)] = now
        if old is None or now - old >= self._timeout:
            self._changed()  # a new watcher (a known one's requests ride the next refresh)

    def connect(self, rig_id: str, username: str) -> int:
        """Note a live connection; return a handle for :meth:`disconnect`."""
        now = self._clock.now()
        with self._lock:
            handle = next(self._handles)
            self._connections[handle] = (rig_id, username)
            self._seen[(rig_id, username)] = now
        self._changed()
        return handle

    def disconnect(self, handle: int) -> None:
        """Forget a live connection (unknown handles are ignored)."""
        now = self._clock.now()
        with self._lock:
            key = self._connections.pop(handle, None)
            if key is not None:
                self._seen[key] = now
        if key is not None:
            self._changed()

    def watchers(self, rig_id: str) -> list[Watcher]:
        """Return the users watching ``rig_id``, by user name (on every worker, when shared).

        A user watching on several workers is one watcher: their connections
        added up, their latest contact.
        """
        here = self.here(rig_id).get(rig_id, [])
        elsewhere = self._elsewhere
        if elsewhere is None:
            return here
        now = self._clock.now()
        merged = {w.username: w for w in here}
        for watcher in elsewhere.watchers(rig_id):
            if watcher.connections == 0 and now - watcher.last_seen >= self._timeout:
                continue  # gone since that worker wrote: the same timeout as here
            known = merged.get(watcher.username)
            if known is not None:
                watcher = Watcher(
                    watcher.username,
                    known.connections + watcher.connections,
                    max(known.last_seen, watcher.last_seen),
                )
            merged[watcher.username] = watcher
        return sorted(merged.values(), key=lambda w: w.username)

    def count(self, rig_id: str) -> int:
        """Return how many users watch ``rig_id``."""
        return len(self.watchers(rig_id))

    def here(self, rig_id: str | None = None) -> dict[str, list[Watcher]]:
        """This worker's own watchers of ``rig_id`` (of every rig: ``None``), by rig and name."""
        now = self._clock.now()
        with self._lock:
            counts: dict[tuple[str, str], int] = {}
            for key in self._connections.values():
                if rig_id is None or key[0] == rig_id:
                    counts[key] = counts.get(key, 0) + 1
            result: dict[str, list[Watcher]] = {}
            for (rig, user), seen in list(self._seen.items()):
                if rig_id is not None and rig != rig_id:
                    continue
                live = counts.get((rig, user), 0)
                if live == 0 and now - seen >= self._timeout:
                    del self._seen[(rig, user)]
                    continue
                result.setdefault(rig, []).append(Watcher(user, live, seen))
        return {rig: _by_name(found) for rig, found in result.items()}

    def _changed(self) -> None:
        elsewhere = self._elsewhere
        if elsewhere is not None:
            elsewhere.changed()


def _by_name(watchers: Iterable[Watcher]) -> list[Watcher]:
    return sorted(watchers, key=lambda w: w.username)
