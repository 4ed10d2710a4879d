"""The tool's own RSA keys: generated on first use, rotated, published as a JWKS.

The newest key that is not retired signs the tool's JWTs (deep-linking
responses, client-credentials assertions). :meth:`ToolKeys.rotate` retires it
and makes a new one; a retired key stays in the published set for
``keep_retired`` (default 7 days) so that platforms that cached the old set,
or still check a message signed just before, keep working.
Keys are 2048-bit RSA (``cryptography``), signed with RS256 (PyJWT), as LTI
1.3 requires.
"""

from __future__ import annotations

import json
import secrets
from datetime import timedelta
from typing import Any

import jwt
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from jwt.algorithms import RSAAlgorithm
from sqlalchemy import or_, select

from thermolab.lab.clock import LabClock
from thermolab.lab.db import Database
from thermolab.lab.db.lti_models import LtiKey

__all__ = ["ToolKeys"]

_KEEP_RETIRED = timedelta(days=7)


class ToolKeys:
    """The tool's signing keys in the database.

    Parameters
    ----------
    db : Database
    clock : LabClock
    keep_retired : timedelta
        How long a retired key stays published.
    """

    def __init__(
        self, db: Database, clock: LabClock, *, keep_retired: timedelta = _KEEP_RETIRED
    ) -> None:
        self._db = db
        self._clock = clock
        self._keep = keep_retired

    def current(self) -> LtiKey:
        """The signing key (made now if there is none)."""
        with self._db.read() as session:
            key = session.scalars(
                select(LtiKey).where(LtiKey.retired_at.is_(None)).order_by(LtiKey.id.desc())
            ).first()
            if key is not None:
                session.expunge(key)
                return key
        return self.rotate()

    def rotate(self) -> LtiKey:
        """Retire the signing key (it stays published a while) and make a new one."""
        private = rsa.generate_private_key(public_exponent=65537, key_size=2048)
        pem = private.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        ).decode("ascii")
        kid = secrets.token_urlsafe(16)
        public: dict[str, Any] = json.loads(RSAAlgorithm.to_jwk(private.public_key()))
        public.update({"kid": kid, "alg": "RS256", "use": "sig"})
        now = self._clock.now()
        with self._db.write() as session:
            for old in session.scalars(select(LtiKey).where(LtiKey.retired_at.is_(None))):
                old.retired_at = now
            key = LtiKey(kid=kid, private_pem=pem, public_jwk=public, created_at=now)
            session.add(key)
            session.flush()
            session.expunge(key)
            return key

    def jwks(self) -> dict[str, Any]:
        """The published key set: the signing key and keys retired less than a while ago."""
        self.current()
        cutoff = self._clock.now() - self._keep
        with self._db.read() as session:
            keys = session.scalars(
                select(LtiKey)
                .where(or_(LtiKey.retired_at.is_(None), LtiKey.retired_at > cutoff))
                .order_by(LtiKey.id.desc())
            )
            return {"keys": [dict(k.public_jwk) for k in keys]}

    def sign(self, claims: dict[str, Any]) -> str:
        """A JWT of ``claims`` signed RS256 with the signing key (its ``kid`` in the header)."""
        key = self.current()
        return jwt.encode(claims, key.private_pem, algorithm="RS256", headers={"kid": key.kid})
