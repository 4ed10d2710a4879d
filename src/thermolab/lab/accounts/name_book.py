"""Display names by login name, for the pages that name people (controller, queue, runs).

The access views and run records carry login names (what the lab decides
on); the HTTP answers add the display names of the people they name, looked
up here. A name is kept for :data:`TTL` seconds, so that a rig polled every
second does not read the users table each time, while a name changed by a
class list in this server shows at once (the routes that change names call
:meth:`NameBook.forget`), one changed from another process (``thermolab course``) within that time.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable
from datetime import datetime, timedelta

from sqlalchemy import select

from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.models import User

__all__ = ["TTL", "NameBook"]

TTL = 30.0
"""Seconds a display name is kept before it is read again."""

_MAX_CACHED = 10_000


class NameBook:
    """Login name -> display name, read from the users table and kept briefly.

    Parameters
    ----------
    db : Database
    clock : LabClock
    """

    def __init__(self, db: Database, clock: LabClock) -> None:
        self._db = db
        self._clock = clock
        self._lock = threading.Lock()
        self._known: dict[str, tuple[str | None, datetime]] = {}

    def forget(self) -> None:
        """Drop every kept name (this process changed someone's name)."""
        with self._lock:
            self._known.clear()

    def names(self, usernames: Iterable[str | None]) -> dict[str, str]:
        """The display names of ``usernames`` that have one (others are left out)."""
        wanted = {u for u in usernames if u}
        if not wanted:
            return {}
        now = self._clock.now()
        fresh = now - timedelta(seconds=TTL)
        with self._lock:
            stale = {u for u in wanted if u not in self._known or self._known[u][1] < fresh}
        if stale:
            with self._db.read() as session:
                rows = session.execute(
                    select(User.username, User.display_name).where(User.username.in_(stale))
                ).all()
            found = {str(u): d for u, d in rows}
            with self._lock:
                if len(self._known) > _MAX_CACHED:
                    self._known.clear()
                for u in stale:
                    self._known[u] = (found.get(u), now)
        with self._lock:
            out = {u: self._known[u][0] for u in wanted if u in self._known}
        return {u: d for u, d in out.items() if d}
