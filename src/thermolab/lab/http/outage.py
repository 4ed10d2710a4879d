"""A database that stops answering: 503 ``database_unavailable``, logged once per outage.

When PostgreSQL goes away (a restart, a failover, a full disk, connections
refused) or SQLite stays locked past its busy timeout, SQLAlchemy raises
``OperationalError`` (or ``InterfaceError``, ``TimeoutError`` when the pool
waits in vain). Without a handler each would be a 500 with a traceback in the
log for every request. The lab answers them as the documented error instead:
503, the stable code ``database_unavailable``, its sentence in the reader's
language and ``Retry-After`` (the browser's pages and the clients wait that
long and try again), and it logs the outage once: the first refusal with
its cause, then, when a request fails after :data:`QUIET` seconds without a
failure, a new outage. The count of refused requests of the one before is
logged with it. Nothing already recorded is touched: the failed request
changed nothing (its transaction never committed).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from sqlalchemy.exc import InterfaceError, OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeoutError

from thermolab.lab.http.errors import error_response, request_language

__all__ = ["QUIET", "RETRY_AFTER", "DatabaseOutage", "install_outage_handler"]

log = logging.getLogger(__name__)

RETRY_AFTER = 5
"""Seconds a client is told to wait before trying again."""
QUIET = 30.0
"""Seconds without a refusal after which the next one begins a new outage (logged again)."""


class DatabaseOutage:
    """The outage in progress, if any: when it began and how many requests it refused.

    Parameters
    ----------
    clock : callable, optional
        Monotonic seconds (default :func:`time.monotonic`).

    Examples
    --------
    >>> now = [0.0]
    >>> outage = DatabaseOutage(clock=lambda: now[0])
    >>> outage.refused("connection refused"), outage.refused("connection refused")
    (True, False)
    >>> now[0] = 31.0
    >>> outage.refused("connection refused")  # 30 s quiet: a new outage
    True
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._last: float | None = None
        self.count = 0

    def refused(self, cause: str) -> bool:
        """Count a refused request; ``True`` (and logged) when it begins an outage."""
        with self._lock:
            now = self._clock()
            new = self._last is None or now - self._last > QUIET
            if new and self._last is not None:
                log.warning("the database outage ended; it refused %d requests", self.count)
            if new:
                self.count = 0
                log.error(
                    "the database does not answer (%s); requests get 503 database_unavailable "
                    "until it does",
                    cause,
                )
            self.count += 1
            self._last = now
            return new


def _cause(exc: BaseException) -> str:
    """The first line of the driver's reason (no SQL, no parameters)."""
    orig = getattr(exc, "orig", None)
    text = str(orig if orig is not None else exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def install_outage_handler(app: FastAPI, outage: DatabaseOutage | None = None) -> DatabaseOutage:
    """Answer the database's absence as 503 ``database_unavailable``; return the outage state."""
    state = outage if outage is not None else DatabaseOutage()

    async def unavailable(request: Request, exc: Exception) -> JSONResponse:
        state.refused(_cause(exc))
        return error_response(
            503,
            "the lab's database does not answer; try again in a few seconds",
            "database_unavailable",
            {"Retry-After": str(RETRY_AFTER)},
            language=request_language(request.headers, request.cookies),
        )

    for error in (OperationalError, InterfaceError, PoolTimeoutError):
        app.add_exception_handler(error, unavailable)
    return state
