"""The tables of a teacher's grading tools: mark overrides, deadline extensions, lab groups.

Kept apart from :mod:`.models` (same :class:`~.models.Base`, same metadata)
and imported by ``thermolab.lab.db``, as every ``*_models`` module is.

* :class:`GradeOverride` — a teacher's mark for one student on one
  assignment, with the comment the student reads; the automatic mark stays on
  the hand-in (``submissions.mark``), beside it. One per student and
  assignment; it outlives a later hand-in until a teacher removes it.
* :class:`DeadlineExtension` — one student's later deadline for one assignment.
* :class:`LabGroup` and :class:`LabGroupMember` — students of a course who
  share a run and a hand-in. A student is in at most one group of a course
  (a unique index on ``(course_id, user_id)``, the database's own guarantee).
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import Float, ForeignKey, Integer, String, Text, UniqueConstraint
from sqlalchemy.orm import Mapped, mapped_column

from thermolab.lab.db.models import Base, UTCDateTime

__all__ = ["DeadlineExtension", "GradeOverride", "LabGroup", "LabGroupMember"]


class GradeOverride(Base):
    """A teacher's mark for a student on an assignment, and why."""

    __tablename__ = "grade_overrides"
    __table_args__ = (UniqueConstraint("assignment_id", "user_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    assignment_id: Mapped[int] = mapped_column(
        ForeignKey("assignments.id", ondelete="CASCADE"), index=True
    )
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    mark: Mapped[float] = mapped_column(Float)
    comment: Mapped[str] = mapped_column(Text)
    set_by: Mapped[str] = mapped_column(String(64))
    set_at: Mapped[datetime] = mapped_column(UTCDateTime)


class DeadlineExtension(Base):
    """One student's own deadline for an assignment (later than the course's)."""

    __tablename__ = "deadline_extensions"
    __table_args__ = (UniqueConstraint("assignment_id", "user_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    assignment_id: Mapped[int] = mapped_column(
        ForeignKey("assignments.id", ondelete="CASCADE"), index=True
    )
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    deadline: Mapped[datetime] = mapped_column(UTCDateTime)
    set_by: Mapped[str] = mapped_column(String(64))
    set_at: Mapped[datetime] = mapped_column(UTCDateTime)


class LabGroup(Base):
    """Students of a course who work at the rig together and hand in once."""

    __tablename__ = "lab_groups"
    __table_args__ = (UniqueConstraint("course_id", "name"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(64))
    created_by: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)


class LabGroupMember(Base):
    """A student in a lab group (``course_id`` repeated: one group per student and course)."""

    __tablename__ = "lab_group_members"
    __table_args__ = (UniqueConstraint("course_id", "user_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    group_id: Mapped[int] = mapped_column(
        ForeignKey("lab_groups.id", ondelete="CASCADE"), index=True
    )
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id", ondelete="CASCADE"))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
