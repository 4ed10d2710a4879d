"""One server process per database: a lease row, held and renewed by that process.

Two ``thermolab serve`` on one database would each hand the same rig to a
different student and each mark the other's runs interrupted at start-up. The
server therefore takes the database's lease before anything else: one row in
``server_lease``, naming the holder (host, process id, a random token) and
when the lease runs out. The holder renews it on every sweep (about once a
second); another process may take it over only when it has run out, or at
once when the holder is a process of the same host that no longer exists
(``kill -9``: the next start need not wait). A process that finds the lease
held refuses to start (:class:`LeaseHeldError`), before start-up touches any
run or control session. A standby worker of a fleet (``docs/fleet.md``) asks
:meth:`DatabaseLease.lapsed` about once a second and, when it is, takes the
lease with :meth:`DatabaseLease.acquire` like a starting server: of several
standbys, exactly one wins (tests/lab/test_lease_race.py). Written by hand:
no library keeps a lease in a SQL database that both SQLite and PostgreSQL
serve.
"""

from __future__ import annotations

import os
import socket
from datetime import timedelta

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from thermolab.errors import ConflictError
from thermolab.lab.accounts.security import new_token
from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.models import ServerLease

__all__ = ["LEASE_TTL", "DatabaseLease", "LeaseHeldError"]

LEASE_TTL = timedelta(seconds=15)
"""A lease not renewed for this long may be taken over (the holder renews every ~1 s)."""


class LeaseHeldError(ConflictError):
    """Another live server process holds the database's lease."""


class DatabaseLease:
    """This process's claim on being the one server of a database.

    Parameters
    ----------
    db : Database
    clock : LabClock
    ttl : timedelta, optional
        How long the lease lasts unless renewed.
    """

    def __init__(self, db: Database, clock: LabClock, ttl: timedelta = LEASE_TTL) -> None:
        self._db = db
        self._clock = clock
        self._ttl = ttl
        self.host = socket.gethostname()
        self.pid = os.getpid()
        self.token = new_token()
        self.held = False
        self.lost = False
        """``True`` once a renewal found the lease taken by another process."""

    def acquire(self) -> None:
        """Take the lease, or refuse.

        Raises
        ------
        LeaseHeldError
            If another process holds it and is not known to be gone.
        """
        try:
            self._take()
        except IntegrityError:
            # Another process inserted the first lease row at the same moment (no row to
            # lock yet): it won the race (tests/lab/test_lease_race.py).
            raise LeaseHeldError(
                f"the database {self._db.display_url} was just taken by another server "
                "process (one server per database)"
            ) from None
        self.held = True

    def _take(self) -> None:
        with self._db.write() as session:
            now = self._clock.now()
            lease = session.scalars(
                select(ServerLease).where(ServerLease.id == 1).with_for_update()
            ).one_or_none()
            if lease is None:
                lease = ServerLease(id=1)
                session.add(lease)
            elif lease.token != self.token and lease.expires_at > now and not self._gone(lease):
                raise LeaseHeldError(
                    f"the database {self._db.display_url} is already served by process "
                    f"{lease.pid} on {lease.host} (since {lease.acquired_at:%Y-%m-%d %H:%M:%S} "
                    "UTC); stop that server first (one server per database), or wait "
                    f"{self._ttl.total_seconds():g} s after it is gone"
                )
            lease.host, lease.pid, lease.token = self.host, self.pid, self.token
            lease.acquired_at = now
            lease.expires_at = now + self._ttl

    def lapsed(self) -> bool:
        """Whether the lease is free to take now: no row, run out, or its holder gone.

        A read only (a standby worker asks it about once a second); taking it
        is :meth:`acquire`'s, under the row lock, so of several askers one wins.
        """
        with self._db.read() as session:
            lease = session.get(ServerLease, 1)
            if lease is None or lease.token == self.token:
                return lease is None
            return lease.expires_at <= self._clock.now() or self._gone(lease)

    def renew(self) -> bool:
        """Extend the lease; ``False`` if another process has taken it meanwhile."""
        with self._db.write() as session:
            lease = session.get(ServerLease, 1)
            if lease is None or lease.token != self.token:
                self.held = False
                self.lost = True
                return False
            lease.expires_at = self._clock.now() + self._ttl
        return True

    def release(self) -> None:
        """Give the lease up (the server is stopping); no effect if not held."""
        if not self.held:
            return
        with self._db.write() as session:
            lease = session.get(ServerLease, 1)
            if lease is not None and lease.token == self.token:
                session.delete(lease)
        self.held = False

    def _gone(self, lease: ServerLease) -> bool:
        # Only a process of this host can be checked; elsewhere the lease must run out.
        if lease.host != self.host:
            return False
        return not _alive(lease.pid)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    return True
