"""The live stream's logins: a connection lives as long as the login it was opened with.

The lab announces every login it ends (logout, expiry, a password change, an
account removed) as a :class:`~thermolab.lab.accounts.users.LoginsEnded` event, and
:class:`LoginWatch` closes those clients with 4401 at once; a check every few
seconds catches logins ended by another process (an account removed from the
command line). Revoking an API token closes its connections the same way
(:attr:`Lab.tokens` ``.revoked``).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Collection

import anyio.to_thread
from sqlalchemy import select

from thermolab.lab.db.models import LoginSession
from thermolab.lab.live.fanout import CLOSE_UNAUTHORIZED, LiveFanout
from thermolab.lab.service import Lab

__all__ = ["LoginWatch"]

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

    def __init__(self, lab: Lab, fanout: LiveFanout) -> None:
        self._lab = lab
        self._fanout = fanout
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
        for client in self._fanout.clients():
            if client.key.token_id is None and client.key.session_id in session_ids:
                client.close(CLOSE_UNAUTHORIZED, "your session has ended; log in again")

    def tokens_revoked(self, token_ids: frozenset[int]) -> None:
        """Close the connections of API tokens that were revoked (any thread)."""
        loop = self._fanout.loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._close_tokens, token_ids)

    def _close_tokens(self, token_ids: frozenset[int]) -> None:
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
                for client in clients:
                    if client.key.token_id is None and client.key.session_id not in alive:
                        client.close(CLOSE_UNAUTHORIZED, "your session has ended; log in again")
            if tokens:
                live = await anyio.to_thread.run_sync(self._lab.tokens.alive, tokens)
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


def _log_failure(task: asyncio.Future[None]) -> None:
    if not task.cancelled() and task.exception() is not None:
        log.error("live login check failed", exc_info=task.exception())
