"""What a launch hands to a later request: :class:`Handoffs`, in the database.

A deep-linking launch leaves the teacher's request waiting for their choice;
a launch whose frame has no cookies leaves a ticket for a new window. The
later request may reach another web worker (``thermolab serve --workers``,
a fleet), so this state is a row of ``lti_handoffs``, not a process's
memory: keyed by the SHA-256 of a random key (the key itself is only in the
browser's URL), bound to its person and platform, expiring on the lab clock,
and used once — :meth:`Handoffs.take` deletes the row in the transaction that
reads it, so two workers racing for one key cannot both get it.
"""

from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.lti_models import HandoffKind, LtiHandoff, LtiPlatform
from thermolab.lab.lti.platforms import PlatformInfo

__all__ = ["Handoff", "Handoffs"]


@dataclass(frozen=True, slots=True)
class Handoff:
    """A waiting handoff: whose, from which platform, its kind's data, until when."""

    user_id: int
    platform: PlatformInfo
    data: dict[str, Any]
    expires: datetime


def _hash(key: str) -> str:
    return hashlib.sha256(key.encode("utf-8")).hexdigest()


class Handoffs:
    """Handoffs of every kind, in ``lti_handoffs``.

    Parameters
    ----------
    db : Database
    clock : LabClock
        Decides expiry (every worker's clock agrees through NTP).
    """

    def __init__(self, db: Database, clock: LabClock) -> None:
        self._db = db
        self._clock = clock

    def put(
        self,
        kind: HandoffKind,
        user_id: int,
        platform_id: int,
        data: dict[str, Any],
        lifetime: timedelta,
    ) -> str:
        """Keep a handoff for ``lifetime``; return its key (forgetting expired ones)."""
        key = secrets.token_urlsafe(32)
        now = self._clock.now()
        with self._db.write() as session:
            session.execute(delete(LtiHandoff).where(LtiHandoff.expires_at <= now))
            session.add(
                LtiHandoff(
                    key_hash=_hash(key),
                    kind=kind.value,
                    user_id=user_id,
                    platform_id=platform_id,
                    data=data,
                    expires_at=now + lifetime,
                )
            )
        return key

    def peek(self, kind: HandoffKind, key: str) -> Handoff | None:
        """The unexpired handoff of ``key`` (left in place); ``None`` when unknown."""
        with self._db.read() as session:
            return self._found(session, kind, key)

    def take(self, kind: HandoffKind, key: str) -> Handoff | None:
        """The unexpired handoff of ``key``, removed: a second take gets ``None``."""
        with self._db.write() as session:
            found = self._found(session, kind, key)
            if found is None:
                return None
            gone = session.execute(delete(LtiHandoff).where(LtiHandoff.key_hash == _hash(key)))
            # Another worker's take deleted it between our read and our delete.
            return found if getattr(gone, "rowcount", 1) == 1 else None

    def _found(self, session: Session, kind: HandoffKind, key: str) -> Handoff | None:
        row = session.execute(
            select(LtiHandoff, LtiPlatform)
            .join(LtiPlatform, LtiPlatform.id == LtiHandoff.platform_id)
            .where(LtiHandoff.key_hash == _hash(key), LtiHandoff.kind == kind.value)
        ).one_or_none()
        if row is None or row[0].expires_at <= self._clock.now():
            return None
        handoff, platform = row
        return Handoff(
            handoff.user_id, PlatformInfo.of(platform), dict(handoff.data), handoff.expires_at
        )
