"""The LTI 1.3 tool's tables (issue #12), on the lab's :class:`~thermolab.lab.db.models.Base`.

* ``lti_platforms``: a registered LMS (issuer, client id, its URLs, deployment ids).
* ``lti_keys``: the tool's own RSA keys; the newest unretired one signs, a
  retired one stays published for a while after a rotation.
* ``lti_login_states``: one per OIDC login initiation (state stored as its
  SHA-256, nonce, expiry, when used): a state and its nonce work once.
* ``lti_identities``: an LMS user (platform, ``sub``) and the lab account it signs in as.
* ``lti_contexts``: an LMS course (platform, context id) and the lab course it fills.
* ``lti_resource_links``: an activity placed in an LMS course, what it opens
  and its gradebook column (AGS line item), for the grades of that target.
* ``lti_grades``: the grade outbox (AGS): scores queued, posted, retried.
* ``lti_handoffs``: what a launch hands to a later request, perhaps on another
  worker — a pending deep-linking request, a new window's ticket — keyed by
  the SHA-256 of its random key, deleted when used or expired.
"""

from __future__ import annotations

import enum
from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    CheckConstraint,
    Float,
    ForeignKey,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = [
    "GradeStatus",
    "HandoffKind",
    "LtiContext",
    "LtiGrade",
    "LtiHandoff",
    "LtiIdentity",
    "LtiKey",
    "LtiLoginState",
    "LtiPlatform",
    "LtiResourceLink",
]

URL_LENGTH = 1024


class GradeStatus(enum.StrEnum):
    """Where a queued grade is: waiting (or retrying), posted, or given up on."""

    PENDING = "pending"
    SENT = "sent"
    FAILED = "failed"


class HandoffKind(enum.StrEnum):
    """What an :class:`LtiHandoff` waits for."""

    DEEP_LINK = "deep_link"  # a teacher's choice of what to link
    WINDOW = "window"  # a new window's first-party login (cookies blocked in the frame)


class LtiPlatform(Base):
    """A learning management system registered by a teacher."""

    __tablename__ = "lti_platforms"
    __table_args__ = (UniqueConstraint("issuer", "client_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    issuer: Mapped[str] = mapped_column(String(255))
    client_id: Mapped[str] = mapped_column(String(255))
    auth_login_url: Mapped[str] = mapped_column(String(URL_LENGTH))
    token_url: Mapped[str] = mapped_column(String(URL_LENGTH))
    jwks_url: Mapped[str] = mapped_column(String(URL_LENGTH))
    deployment_ids: Mapped[list[Any]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)


class LtiKey(Base):
    """One of the tool's RSA key pairs (PEM private key, public JWK)."""

    __tablename__ = "lti_keys"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    kid: Mapped[str] = mapped_column(String(64), unique=True)
    private_pem: Mapped[str] = mapped_column(Text)
    public_jwk: Mapped[dict[str, Any]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)
    retired_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class LtiLoginState(Base):
    """An OIDC login initiation: its state (hashed), nonce and expiry, used once."""

    __tablename__ = "lti_login_states"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    state_hash: Mapped[str] = mapped_column(String(64), unique=True)
    nonce: Mapped[str] = mapped_column(String(64), unique=True)
    platform_id: Mapped[int] = mapped_column(
        ForeignKey("lti_platforms.id", ondelete="CASCADE"), index=True
    )
    expires_at: Mapped[datetime] = mapped_column(UTCDateTime)
    used_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class LtiIdentity(Base):
    """The lab account an LMS user (platform, ``sub``) signs in as."""

    __tablename__ = "lti_identities"
    __table_args__ = (UniqueConstraint("platform_id", "sub"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    platform_id: Mapped[int] = mapped_column(
        ForeignKey("lti_platforms.id", ondelete="CASCADE"), index=True
    )
    sub: Mapped[str] = mapped_column(String(255))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)


class LtiContext(Base):
    """The lab course an LMS course (platform, context id) fills, and its service URLs."""

    __tablename__ = "lti_contexts"
    __table_args__ = (UniqueConstraint("platform_id", "context_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    platform_id: Mapped[int] = mapped_column(
        ForeignKey("lti_platforms.id", ondelete="CASCADE"), index=True
    )
    context_id: Mapped[str] = mapped_column(String(255))
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id", ondelete="CASCADE"), index=True)
    memberships_url: Mapped[str | None] = mapped_column(String(URL_LENGTH))
    lineitems_url: Mapped[str | None] = mapped_column(String(URL_LENGTH))


class LtiResourceLink(Base):
    """An activity placed in an LMS course: what it opens, and its gradebook line item."""

    __tablename__ = "lti_resource_links"
    __table_args__ = (UniqueConstraint("platform_id", "link_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    platform_id: Mapped[int] = mapped_column(
        ForeignKey("lti_platforms.id", ondelete="CASCADE"), index=True
    )
    link_id: Mapped[str] = mapped_column(String(255))
    target: Mapped[str | None] = mapped_column(String(255), index=True)
    lineitem_url: Mapped[str | None] = mapped_column(String(URL_LENGTH))


class LtiGrade(Base):
    """A score for the LMS's gradebook (AGS), queued, then posted or retried."""

    __tablename__ = "lti_grades"
    __table_args__ = (
        CheckConstraint(
            "status IN (" + ", ".join(repr(s.value) for s in GradeStatus) + ")", name="status"
        ),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    platform_id: Mapped[int] = mapped_column(
        ForeignKey("lti_platforms.id", ondelete="CASCADE"), index=True
    )
    lineitem_url: Mapped[str] = mapped_column(String(URL_LENGTH))
    sub: Mapped[str] = mapped_column(String(255))
    score_given: Mapped[float] = mapped_column(Float)
    score_maximum: Mapped[float] = mapped_column(Float)
    comment: Mapped[str | None] = mapped_column(Text)
    timestamp: Mapped[datetime] = mapped_column(UTCDateTime)
    status: Mapped[str] = mapped_column(String(16), index=True)
    attempts: Mapped[int] = mapped_column(Integer)
    next_attempt_at: Mapped[datetime] = mapped_column(UTCDateTime)
    last_error: Mapped[str | None] = mapped_column(Text)
    sent_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class LtiHandoff(Base):
    """A launch's state kept for a later request (any worker), used once, until it expires.

    ``data`` is the kind's: a deep-linking request's deployment, settings and
    lab course; a window's page to open.
    """

    __tablename__ = "lti_handoffs"
    __table_args__ = (
        CheckConstraint(
            "kind IN (" + ", ".join(repr(k.value) for k in HandoffKind) + ")", name="kind"
        ),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    key_hash: Mapped[str] = mapped_column(String(64), unique=True)
    kind: Mapped[str] = mapped_column(String(16))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    platform_id: Mapped[int] = mapped_column(
        ForeignKey("lti_platforms.id", ondelete="CASCADE"), index=True
    )
    data: Mapped[dict[str, Any]] = mapped_column(JSON)
    expires_at: Mapped[datetime] = mapped_column(UTCDateTime, index=True)
