"""The tables of assignments and their hand-ins (``thermolab.lab.assignments``).

Kept apart from :mod:`.models` (same :class:`~.models.Base`, same metadata):
``thermolab.lab.db`` imports this module, so the metadata the migrations are
compared with is complete wherever the database is used.

Every hand-in is kept (the history of a student's attempts); the newest of a
student for an assignment is the ``current`` one, the one the grades show.
At most one current hand-in per student and assignment is a partial unique
index, the database's own guarantee.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, Boolean, Float, ForeignKey, Index, Integer, String, Text, false, text
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["Assignment", "Submission"]


class Assignment(Base):
    """An experiment a course's teacher sets: rig, methods and settings, tolerances, deadline.

    ``methods`` lists registry names (:mod:`thermolab.ident.registry`);
    ``settings`` maps a method to the settings the teacher gave it (checked by
    the registry). Tolerances are relative on Ks and Ts, absolute (seconds) on
    θ; ``tol_theta`` null: θ is not asked. A ``draft`` (copied from last term's
    course) is its teachers' only until they publish it.
    """

    __tablename__ = "assignments"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id", ondelete="CASCADE"), index=True)
    title: Mapped[str] = mapped_column(String(200))
    instructions: Mapped[str] = mapped_column(Text)
    rig_id: Mapped[str] = mapped_column(String(64))
    methods: Mapped[list[Any]] = mapped_column(JSON)
    settings: Mapped[dict[str, Any]] = mapped_column(JSON)
    tol_k: Mapped[float] = mapped_column(Float)
    tol_tau: Mapped[float] = mapped_column(Float)
    tol_theta: Mapped[float | None] = mapped_column(Float)
    deadline: Mapped[datetime] = mapped_column(UTCDateTime)
    created_by: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime)
    draft: Mapped[bool] = mapped_column(Boolean, default=False, server_default=false())


class Submission(Base):
    """A student's hand-in: their run, their answers, and the automatic assessment.

    ``mark`` is null when the assessment gives none (state ``review``: the
    run's identification is not trustworthy); ``assessment`` holds the
    feedback, check by check.
    """

    __tablename__ = "submissions"
    __table_args__ = (
        Index(
            "ux_submissions_current",
            "assignment_id",
            "user_id",
            unique=True,
            sqlite_where=text("current"),
            postgresql_where=text("current"),
        ),
        Index("ix_submissions_assignment_id", "assignment_id"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    assignment_id: Mapped[int] = mapped_column(ForeignKey("assignments.id", ondelete="CASCADE"))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"))
    username: Mapped[str] = mapped_column(String(64))
    run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id", ondelete="SET NULL"))
    answers: Mapped[dict[str, Any]] = mapped_column(JSON)
    submitted_at: Mapped[datetime] = mapped_column(UTCDateTime)
    late: Mapped[bool] = mapped_column(Boolean)
    current: Mapped[bool] = mapped_column(Boolean)
    state: Mapped[str] = mapped_column(String(16))
    mark: Mapped[float | None] = mapped_column(Float)
    max_mark: Mapped[float] = mapped_column(Float)
    assessment: Mapped[dict[str, Any]] = mapped_column(JSON)
    marked_at: Mapped[datetime] = mapped_column(UTCDateTime)
    #: The group member who handed in for this student (null: the student themself).
    handed_in_by: Mapped[str | None] = mapped_column(String(64))
