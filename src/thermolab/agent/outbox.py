"""The agent's durable outbox: every sample and run end, kept until the lab has it.

A SQLite file on the rig host (the standard library's ``sqlite3``: nothing to
install, crash-safe, one writer). Each message gets the next sequence number
when it is written, before it is sent; the lab acknowledges the highest
number it has stored and only then is anything deleted. A link lost for any
length of time, or an agent restarted, loses nothing: what is left is sent
again, in order, and the lab's store ignores what it already holds.

``synchronous=FULL`` in WAL mode: a committed sample survives a power cut of
the rig host, at a cost (one fsync per commit) that a 10 samples/s runner
does not notice.
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path

__all__ = ["Outbox"]


class Outbox:
    """Numbered messages (JSON bodies without their ``seq``) waiting for the lab's ack.

    Parameters
    ----------
    path : str or Path
        The SQLite file (``":memory:"`` for tests that need no durability).

    Examples
    --------
    >>> box = Outbox(":memory:")
    >>> box.append("sample", '{"k": 0}'), box.append("sample", '{"k": 1}')
    (1, 2)
    >>> box.ack(1)
    >>> box.pending()
    [(2, 'sample', '{"k": 1}')]
    """

    def __init__(self, path: str | Path) -> None:
        self._lock = threading.Lock()
        self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=FULL")
        self._db.execute(
            "CREATE TABLE IF NOT EXISTS outbox ("
            " seq INTEGER PRIMARY KEY AUTOINCREMENT, kind TEXT NOT NULL, body TEXT NOT NULL)"
        )

    def append(self, kind: str, body: str) -> int:
        """Store one message durably and return its sequence number."""
        with self._lock:
            cursor = self._db.execute("INSERT INTO outbox (kind, body) VALUES (?, ?)", (kind, body))
            seq = cursor.lastrowid
        assert seq is not None
        return seq

    def pending(self, after: int = 0, limit: int = 500) -> list[tuple[int, str, str]]:
        """Return up to ``limit`` messages after ``after``, oldest first: ``(seq, kind, body)``."""
        with self._lock:
            rows = self._db.execute(
                "SELECT seq, kind, body FROM outbox WHERE seq > ? ORDER BY seq LIMIT ?",
                (after, limit),
            ).fetchall()
        return [(int(s), str(k), str(b)) for s, k, b in rows]

    def ack(self, seq: int) -> None:
        """The lab holds everything up to ``seq``: forget it."""
        with self._lock:
            self._db.execute("DELETE FROM outbox WHERE seq <= ?", (seq,))

    def count(self) -> int:
        """Messages not yet acknowledged."""
        with self._lock:
            (n,) = self._db.execute("SELECT count(*) FROM outbox").fetchone()
        return int(n)

    def close(self) -> None:
        """Close the file (everything written is already durable)."""
        with self._lock:
            self._db.close()
