"""The audit log (:mod:`thermolab.lab.audit`): one row per privileged action.

Rows are only ever added: who acted (login name, kept when the account is
removed), what they did (a stable action name), on what (a user, a course, a
rig or a platform, as text), when, from which address, and a short JSON detail
(never a password or a token).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["AuditEntry"]


class AuditEntry(Base):
    """A privileged action: who, what, on whom, when, from where."""

    __tablename__ = "audit_log"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    at: Mapped[datetime] = mapped_column(UTCDateTime, index=True)
    actor: Mapped[str] = mapped_column(String(64))
    action: Mapped[str] = mapped_column(String(48), index=True)
    target: Mapped[str] = mapped_column(String(200))
    address: Mapped[str | None] = mapped_column(String(64))
    detail: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
