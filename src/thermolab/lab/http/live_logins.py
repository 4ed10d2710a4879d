"""The live stream's logins: a connection lives as long as the login it was opened with.

The lab announces every login it ends (logout, expiry, a password change, an
account removed) as a :class:`~thermolab.lab.accounts.users.LoginsEnded` event, and
:class:`LoginWatch` closes those clients with 4401 at once; a check every few
seconds catches logins ended by another process (an account removed from the
command line). Revoking an API token closes its connections the same way
(:attr:`Lab.tokens` ``.revoked``).

:class:`KnownLogins` remembers, for a few seconds, whom each credential that
opened a live socket belongs to: when a lecture hall's pages all reconnect, or
a class opens the rig at the bell, a join whose login was just seen is a dict
lookup in the event loop, not a store round trip in a worker thread (a
thousand of those, holding the GIL, delayed the watchers' samples). Logins
this lab ends are forgotten at once; those another process ends are caught by
the same periodic check that closes their connections.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Awaitable, Callable, Collection
from datetime import datetime, timedelta

import anyio.to_thread
from sqlalchemy import select

from thermolab.lab.accounts.security import hash_token
from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.login_models import LoginSession
from thermolab.lab.http.credentials import resolve_principal
from thermolab.lab.live.fanout import CLOSE_UNAUTHORIZED, LiveFanout
from thermolab.lab.service import Lab

__all__ = ["KnownLogins", "LoginWatch"]

_MOST_KNOWN = 10_000
"""Credentials remembered at most (a lecture hall's worth, many times over)."""

log = logging.getLogger(__name__)


class LoginWatch:
    """Closes the live clients whose login ended or whose API token was revoked.

    Parameters
    ----------
    lab : Lab
        Its :attr:`~Lab.logins_ended` and ``tokens.revoked`` events are listened to.
    fanout : LiveFanout
        The live stream's clients.
    """

    def __init__(self, lab: Lab, fanout: LiveFanout, known: KnownLogins | None = None) -> None:
        self._lab = lab
        self._fanout = fanout
        self._known = known
        self._checking: asyncio.Task[None] | None = None
        self._check_again = False
        self._watchdog: asyncio.Task[None] | None = None
        lab.logins_ended.subscribe(self.logins_ended)
        lab.tokens.revoked.subscribe(self.tokens_revoked)

    def bind(self, loop: asyncio.AbstractEventLoop | None, interval: float | None) -> None:
        """Check every ``interval`` seconds on ``loop`` (``None``: stop checking)."""
        if self._watchdog is not None:
            self._watchdog.cancel()
            self._watchdog = None
        if loop is not None and interval is not None:
            self._watchdog = loop.create_task(self._check_sessions_forever(interval))

    async def _check_sessions_forever(self, interval: float) -> None:
        while True:
            await asyncio.sleep(interval)
            self._check_sessions()

    def logins_ended(self, session_ids: frozenset[int]) -> None:
        """Close the connections of logins that ended (any thread)."""
        loop = self._fanout.loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._close_logins, session_ids)

    def _close_logins(self, session_ids: frozenset[int]) -> None:
        if self._known is not None:
            self._known.forget(sessions=session_ids)
        for client in self._fanout.clients():
            if client.key.token_id is None and client.key.session_id in session_ids:
                client.close(CLOSE_UNAUTHORIZED, "your session has ended; log in again")

    def tokens_revoked(self, token_ids: frozenset[int]) -> None:
        """Close the connections of API tokens that were revoked (any thread)."""
        loop = self._fanout.loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._close_tokens, token_ids)

    def _close_tokens(self, token_ids: frozenset[int]) -> None:
        if self._known is not None:
            self._known.forget(tokens=token_ids)
        for client in self._fanout.clients():
            if client.key.token_id is not None and client.key.token_id in token_ids:
                client.close(CLOSE_UNAUTHORIZED, "this API token was revoked")

    def _check_sessions(self) -> None:
        # One check at a time; a request for one while it runs makes it run again.
        if self._checking is not None and not self._checking.done():
            self._check_again = True
            return
        self._checking = asyncio.ensure_future(self._close_ended_sessions())
        self._checking.add_done_callback(_log_failure)

    async def _close_ended_sessions(self) -> None:
        while True:
            self._check_again = False
            clients = self._fanout.clients()
            ids = {c.key.session_id for c in clients if c.key.token_id is None}
            tokens = {c.key.token_id for c in clients if c.key.token_id is not None}
            if ids:
                alive = await anyio.to_thread.run_sync(self._alive_sessions, ids)
                if self._known is not None:
                    self._known.forget(sessions=ids - alive)
                for client in clients:
                    if client.key.token_id is None and client.key.session_id not in alive:
                        client.close(CLOSE_UNAUTHORIZED, "your session has ended; log in again")
            if tokens:
                live = await anyio.to_thread.run_sync(self._lab.tokens.alive, tokens)
                if self._known is not None:
                    self._known.forget(tokens=tokens - set(live))
                for client in clients:
                    token = client.key.token_id
                    if token is not None and token not in live:
                        client.close(CLOSE_UNAUTHORIZED, "this API token was revoked or expired")
            if not self._check_again:
                return

    def _alive_sessions(self, ids: Collection[int | None]) -> set[int | None]:
        now = self._lab.clock.now()
        wanted = [i for i in ids if i is not None]
        with self._lab.db.read() as session:
            alive: set[int | None] = set(
                session.scalars(
                    select(LoginSession.id).where(
                        LoginSession.id.in_(wanted), LoginSession.expires_at > now
                    )
                )
            )
        return alive


class KnownLogins:
    """Whom recently seen credentials belong to, for ``ttl`` seconds (loop thread).

    Parameters
    ----------
    lab : Lab
        Its store is read for what is not known.
    ttl : float
        Seconds a credential's owner is remembered (0: never), in real time and
        in the lab's: a login whose time runs out meanwhile is read again.
    in_thread : callable
        Runs store work in a worker thread: ``await in_thread(work)``.

    Credentials being read are read once, however many sockets wait for them;
    a login that is refused is not remembered. :attr:`reads` counts the store
    round trips made.
    """

    def __init__(
        self, lab: Lab, ttl: float, in_thread: Callable[..., Awaitable[Principal | None]]
    ) -> None:
        self._lab = lab
        self._ttl = ttl
        self._ttl_lab = timedelta(seconds=ttl)
        self._in_thread = in_thread
        # credential -> who, when it was read (the lab's clock, and time.monotonic())
        self._known: dict[tuple[str, str], tuple[Principal, datetime, float]] = {}
        self._reading: dict[tuple[str, str], asyncio.Future[Principal | None]] = {}
        self._forgotten = 0  # grows with every forget: a read begun before one is not kept
        self.reads = 0

    async def resolve(self, cookie: str | None, authorization: str | None) -> Principal | None:
        """Who the credentials are (a bearer token before a cookie), or ``None``."""
        credential = authorization if authorization is not None else cookie
        if not credential:
            return None
        # Kept by digest, as the store keeps them: no secret stays in memory.
        key = ("bearer" if authorization is not None else "cookie", hash_token(credential))
        now, moment = self._lab.clock.now(), time.monotonic()
        known = self._known.get(key)
        if known is not None:
            who, read_at, read_moment = known
            # Fresh in real time (what the session check lets pass unnoticed) and in the
            # lab's time (a login idle or expired by then is read again, and refused).
            if (
                moment - read_moment < self._ttl
                and timedelta(0) <= now - read_at < self._ttl_lab
                and (who.expires_at is None or now < who.expires_at)
            ):
                return who
            del self._known[key]
        reading = self._reading.get(key)
        if reading is None:
            self.reads += 1
            forgotten = self._forgotten
            read = self._in_thread(
                lambda: resolve_principal(self._lab, cookie=cookie, authorization=authorization)
            )
            reading = self._reading[key] = asyncio.ensure_future(read)

            def done(future: asyncio.Future[Principal | None]) -> None:
                del self._reading[key]
                if future.cancelled() or future.exception() is not None:
                    return
                who = future.result()
                if who is not None and self._ttl > 0 and forgotten == self._forgotten:
                    self._remember(key, (who, now, moment))

            reading.add_done_callback(done)
        # Shielded: a socket that goes while it waits does not end the others' read.
        return await asyncio.shield(reading)

    def _remember(self, key: tuple[str, str], known: tuple[Principal, datetime, float]) -> None:
        if len(self._known) >= _MOST_KNOWN:
            moment = time.monotonic()
            self._known = {k: v for k, v in self._known.items() if moment - v[2] < self._ttl}
            while len(self._known) >= _MOST_KNOWN:  # the oldest first (insertion order)
                del self._known[next(iter(self._known))]
        self._known[key] = known

    def forget(
        self, *, sessions: Collection[int | None] = (), tokens: Collection[int | None] = ()
    ) -> None:
        """Forget the logins that ended and the API tokens that were revoked."""
        if not sessions and not tokens:
            return
        self._forgotten += 1
        ended, revoked = set(sessions), set(tokens)
        for key, (who, _, _) in list(self._known.items()):
            if (who.token_id is None and who.session_id in ended) or (
                who.token_id is not None and who.token_id in revoked
            ):
                del self._known[key]


def _log_failure(task: asyncio.Future[None]) -> None:
    if not task.cancelled() and task.exception() is not None:
        log.error("live login check failed", exc_info=task.exception())
