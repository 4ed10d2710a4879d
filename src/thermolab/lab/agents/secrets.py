"""Per-rig secrets of rig hosts: issued (and rotated) by the lab, stored hashed.

A secret is 256 random bits (``secrets.token_urlsafe``), shown once when
issued; the database keeps its SHA-256, as it does for session tokens: a
value that random needs no slow hash, and a copy of the database does not
let anyone pose as the rig host. Issuing again rotates it: the old secret
stops working at once (the connected host is dropped and must redial with
the new one).
"""

from __future__ import annotations

import hashlib
import hmac
import secrets

from thermolab.errors import NotFoundError
from thermolab.lab.clock import LabClock
from thermolab.lab.config import LabConfig
from thermolab.lab.db import Database
from thermolab.lab.db.agent_models import AgentHost
from thermolab.lab.db.models import RigRow

__all__ = ["check_secret", "issue_secret"]


def _digest(secret: str) -> str:
    return hashlib.sha256(secret.encode()).hexdigest()


def issue_secret(db: Database, config: LabConfig, clock: LabClock, rig_id: str) -> str:
    """Issue (or rotate) the secret of remote rig ``rig_id``; return it (it is not kept).

    Raises
    ------
    NotFoundError
        If the rig is not configured, or not as a remote rig (``agent = true``).
    """
    rig = config.rig(rig_id)
    if not rig.agent:
        raise NotFoundError(
            f"rig {rig_id!r} is not a remote rig; declare it with agent = true in the lab's file"
        )
    secret = secrets.token_urlsafe(32)
    now = clock.now()
    with db.write() as session:
        if session.get(RigRow, rig_id) is None:
            raise NotFoundError(f"rig {rig_id!r} is not in the database yet; start the lab once")
        row = session.get(AgentHost, rig_id)
        if row is None:
            session.add(AgentHost(rig_id=rig_id, secret_hash=_digest(secret), issued_at=now))
        else:
            row.secret_hash = _digest(secret)
            row.issued_at = now
    return secret


def check_secret(db: Database, rig_id: str, secret: str) -> bool:
    """Whether ``secret`` is rig ``rig_id``'s current one (compared in constant time)."""
    with db.read() as session:
        row = session.get(AgentHost, rig_id)
        stored = None if row is None else row.secret_hash
    return stored is not None and hmac.compare_digest(stored, _digest(secret))
