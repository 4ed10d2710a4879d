"""The lab's tables, as typed SQLAlchemy 2 models.

The schema is created and changed only by the Alembic migrations in
``thermolab/lab/migrations`` (a test checks that they and these models agree).
Instants are stored as UTC (:class:`UTCDateTime`); names that appear in
history (who controlled a rig, who sent a command) are copied into the row so
that removing a user keeps the lab's record readable.

Access invariants the database itself enforces (the last line of defence
behind the rig-row lock of :mod:`thermolab.lab.access`):

* at most one active control session per rig (partial unique index on
  ``control_sessions.rig_id`` where ``ended_at IS NULL``);
* at most one active queue entry per user and rig, and queue tickets unique
  per rig;
* at most one running run per rig.
"""

from __future__ import annotations

import enum
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    CheckConstraint,
    DateTime,
    Dialect,
    Float,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    Text,
    UniqueConstraint,
    false,
    text,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column
from sqlalchemy.types import TypeDecorator

__all__ = [
    "Base",
    "Command",
    "ControlSession",
    "Course",
    "CourseMember",
    "CourseRig",
    "LeaveReason",
    "MemberRole",
    "MethodResultRow",
    "PowerState",
    "QueueEntry",
    "RigRow",
    "Role",
    "Run",
    "RunStatus",
    "Sample",
    "ServerLease",
    "TurnEndReason",
    "UTCDateTime",
    "User",
]

# Constraint names are spelled out so that migrations on SQLite and PostgreSQL agree.
NAMING_CONVENTION = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Role(enum.StrEnum):
    """A user's role: students use rigs, teachers also manage them and every user."""

    STUDENT = "student"
    TEACHER = "teacher"


class MemberRole(enum.StrEnum):
    """A person's place in one course: its teacher, a teaching assistant, or a student.

    The values a user's :class:`Role` shares mean the same; an assistant's
    account may be a student's or a teacher's.
    """

    STUDENT = "student"
    TEACHER = "teacher"
    ASSISTANT = "assistant"


class PowerState(enum.StrEnum):
    """Power state of a rig as the lab wants it."""

    OFF = "off"
    ON = "on"
    COOLING = "cooling"


class TurnEndReason(enum.StrEnum):
    """Why a control session ended."""

    RELEASED = "released"
    TIME_LIMIT = "time_limit"
    IDLE = "idle"
    CLIENT_GONE = "client_gone"
    KICKED = "kicked"
    RIG_FAULT = "rig_fault"
    SERVER_RESTART = "server_restart"
    BOOKED = "booked"  # a slot booked for a course the controller is not in began


class LeaveReason(enum.StrEnum):
    """Why an entry left a rig's queue."""

    PROMOTED = "promoted"
    LEFT = "left"
    CLIENT_GONE = "client_gone"
    KICKED = "kicked"
    SERVER_RESTART = "server_restart"
    BOOKED = "booked"  # a slot booked for a course the user is not in began


class RunStatus(enum.StrEnum):
    """Life of an experiment run."""

    RUNNING = "running"
    FINISHED = "finished"
    STOPPED = "stopped"
    INTERRUPTED = "interrupted"
    FAILED = "failed"


def _in(column: str, values: type[enum.StrEnum]) -> str:
    return f"{column} IN ({', '.join(repr(v.value) for v in values)})"


class UTCDateTime(TypeDecorator[datetime]):
    """A timezone-aware UTC instant on every backend.

    SQLite has no time zones: values are stored as naive UTC and given their
    zone back when read. A naive value handed in is refused, since its zone is
    unknowable.
    """

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError(f"refusing a naive datetime {value!r}: the lab stores UTC instants")
        value = value.astimezone(UTC)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class Base(DeclarativeBase):
    """Declarative base of the lab's models."""

    metadata = MetaData(naming_convention=NAMING_CONVENTION)


class User(Base):
    """A person who may log in.

    ``username`` is the login name in its normal form (``thermolab.lab.accounts.names``:
    NFKC, case folded, accents stripped), unique, so names never collide by case
    or accent; ``display_name`` is the name as the person writes it.
    """

    __tablename__ = "users"
    __table_args__ = (CheckConstraint(_in("role", Role), name="role"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    username: Mapped[str] = mapped_column(String(64), unique=True)
    display_name: Mapped[str | None] = mapped_column(String(128))
    role: Mapped[str] = mapped_column(String(16))
    password_hash: Mapped[str] = mapped_column(String(255))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)
    password_changed_at: Mapped[datetime] = mapped_column(UTCDateTime)
    # A teacher's reset gives a temporary password: its holder must choose a new one first.
    must_change_password: Mapped[bool] = mapped_column(Boolean, default=False)
    # A lab administrator: a teacher who also manages what spans courses (accounts, rigs,
    # LTI platforms, the audit log); see thermolab.lab.accounts.policy.
    admin: Mapped[bool] = mapped_column(Boolean, default=False, server_default=false())


class Course(Base):
    """A course: its teachers and students are :class:`CourseMember` rows.

    ``enrol_code`` is what a student types to join (``thermolab.lab.classes.courses``);
    a teacher rotates it to close the door on an old one. A course closed at the
    end of its term (``closed_at`` and the login name ``closed_by``) is read and
    exported, never changed (``thermolab.lab.classes.term``).
    """

    __tablename__ = "courses"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    title: Mapped[str] = mapped_column(String(200))
    enrol_code: Mapped[str] = mapped_column(String(32), unique=True)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)
    closed_at: Mapped[datetime | None] = mapped_column(UTCDateTime, default=None)
    closed_by: Mapped[str | None] = mapped_column(String(64), default=None)


class CourseMember(Base):
    """A user in a course, as a teacher, teaching assistant or student (once per course)."""

    __tablename__ = "course_members"
    __table_args__ = (
        CheckConstraint(_in("role", MemberRole), name="role"),
        UniqueConstraint("course_id", "user_id"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id", ondelete="CASCADE"), index=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    role: Mapped[str] = mapped_column(String(16))
    joined_at: Mapped[datetime] = mapped_column(UTCDateTime)


class CourseRig(Base):
    """A rig a course's students may use; a course with no rows may use every rig."""

    __tablename__ = "course_rigs"
    __table_args__ = (UniqueConstraint("course_id", "rig_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id", ondelete="CASCADE"), index=True)
    rig_id: Mapped[str] = mapped_column(String(64))


class RigRow(Base):
    """Runtime state of a rig (its limits live in the configuration)."""

    __tablename__ = "rigs"
    __table_args__ = (CheckConstraint(_in("power_state", PowerState), name="power_state"),)

    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    title: Mapped[str] = mapped_column(String(200))
    spec: Mapped[str] = mapped_column(String(200))
    configured: Mapped[bool] = mapped_column(Boolean)
    in_service: Mapped[bool] = mapped_column(Boolean)
    power_state: Mapped[str] = mapped_column(String(16))
    power_changed_at: Mapped[datetime] = mapped_column(UTCDateTime)
    vacant_since: Mapped[datetime | None] = mapped_column(UTCDateTime)
    needs_cooldown: Mapped[bool] = mapped_column(Boolean)
    cooling_since: Mapped[datetime | None] = mapped_column(UTCDateTime)
    ambient_output: Mapped[float | None] = mapped_column(Float)
    fault: Mapped[str | None] = mapped_column(Text)
    fault_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    next_ticket: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime)


class ControlSession(Base):
    """One turn of one user at the controls of one rig."""

    __tablename__ = "control_sessions"
    __table_args__ = (
        CheckConstraint(_in("end_reason", TurnEndReason), name="end_reason"),
        CheckConstraint(
            "(ended_at IS NULL AND end_reason IS NULL) "
            "OR (ended_at IS NOT NULL AND end_reason IS NOT NULL)",
            name="ended_with_reason",
        ),
        Index(
            "ux_control_sessions_active_rig",
            "rig_id",
            unique=True,
            sqlite_where=text("ended_at IS NULL"),
            postgresql_where=text("ended_at IS NULL"),
        ),
        Index("ix_control_sessions_rig_id_started_at", "rig_id", "started_at"),
        Index("ix_control_sessions_user_id", "user_id"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    rig_id: Mapped[str] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"))
    user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    username: Mapped[str] = mapped_column(String(64))
    started_at: Mapped[datetime] = mapped_column(UTCDateTime)
    deadline: Mapped[datetime] = mapped_column(UTCDateTime)
    last_heartbeat_at: Mapped[datetime] = mapped_column(UTCDateTime)
    last_activity_at: Mapped[datetime] = mapped_column(UTCDateTime)
    ended_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    end_reason: Mapped[str | None] = mapped_column(String(32))
    ended_by: Mapped[str | None] = mapped_column(String(64))
    # The personal API token the turn was asked for with (null: a login): revoking it ends
    # the turn at once. No foreign key: revoking deletes the token's row.
    token_id: Mapped[int | None] = mapped_column(Integer)


class QueueEntry(Base):
    """A user waiting for control of a rig; FIFO by ``ticket``."""

    __tablename__ = "queue_entries"
    __table_args__ = (
        CheckConstraint(_in("leave_reason", LeaveReason), name="leave_reason"),
        UniqueConstraint("rig_id", "ticket"),
        Index(
            "ux_queue_entries_waiting_user",
            "rig_id",
            "user_id",
            unique=True,
            sqlite_where=text("left_at IS NULL"),
            postgresql_where=text("left_at IS NULL"),
        ),
        Index("ix_queue_entries_user_id", "user_id"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    rig_id: Mapped[str] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"))
    ticket: Mapped[int] = mapped_column(Integer)
    joined_at: Mapped[datetime] = mapped_column(UTCDateTime)
    last_heartbeat_at: Mapped[datetime] = mapped_column(UTCDateTime)
    left_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    leave_reason: Mapped[str | None] = mapped_column(String(32))
    token_id: Mapped[int | None] = mapped_column(Integer)  # as ControlSession's, passed on


class Run(Base):
    """An experiment run on a rig: what was asked, and how it ended."""

    __tablename__ = "runs"
    __table_args__ = (
        CheckConstraint(_in("status", RunStatus), name="status"),
        Index(
            "ux_runs_running_rig",
            "rig_id",
            unique=True,
            sqlite_where=text("status = 'running'"),
            postgresql_where=text("status = 'running'"),
        ),
        Index("ix_runs_rig_id_started_at", "rig_id", "started_at"),
        Index("ix_runs_user_id", "user_id"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    rig_id: Mapped[str] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"))
    control_session_id: Mapped[int | None] = mapped_column(
        ForeignKey("control_sessions.id", ondelete="SET NULL")
    )
    status: Mapped[str] = mapped_column(String(16))
    dt: Mapped[float] = mapped_column(Float)
    n_samples: Mapped[int | None] = mapped_column(Integer)
    signal: Mapped[str | None] = mapped_column(String(200))
    setpoint: Mapped[float | None] = mapped_column(Float)
    methods: Mapped[list[Any]] = mapped_column(JSON)
    meta: Mapped[dict[str, Any]] = mapped_column(JSON)
    started_at: Mapped[datetime] = mapped_column(UTCDateTime)
    ended_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    end_reason: Mapped[str | None] = mapped_column(Text)
    samples_stored: Mapped[int] = mapped_column(Integer)


class Sample(Base):
    """One sample of a run: every channel of :data:`thermolab.records.RUN_CHANNELS`, and extras.

    The runner's standard channels are columns (typed, compact, read in order by
    the export); the channels a rig or controller adds (a set point, a second
    heater) differ from run to run, so they go in ``extra`` as ``{name: value}``
    (JSON; ``null`` for a non-finite value) rather than a table with one row
    per value, which would multiply the rows and make every export a pivot.
    The timing channels are null for samples stored before revision 0004.
    """

    __tablename__ = "samples"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    k: Mapped[int] = mapped_column(Integer, primary_key=True)
    t: Mapped[float] = mapped_column(Float)
    u: Mapped[float] = mapped_column(Float)
    y: Mapped[float] = mapped_column(Float)
    t_read: Mapped[float | None] = mapped_column(Float)
    jitter: Mapped[float | None] = mapped_column(Float)
    lateness: Mapped[float | None] = mapped_column(Float)
    extra: Mapped[dict[str, float | None] | None] = mapped_column(JSON)


class Command(Base):
    """A command a controller gave a rig (input change, run start/stop), with its time."""

    __tablename__ = "commands"
    __table_args__ = (
        Index("ix_commands_rig_id_at", "rig_id", "at"),
        Index("ix_commands_run_id", "run_id"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    rig_id: Mapped[str] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"))
    control_session_id: Mapped[int | None] = mapped_column(
        ForeignKey("control_sessions.id", ondelete="SET NULL")
    )
    run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"))
    user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    username: Mapped[str] = mapped_column(String(64))
    at: Mapped[datetime] = mapped_column(UTCDateTime)
    kind: Mapped[str] = mapped_column(String(32))
    value: Mapped[float | None] = mapped_column(Float)
    payload: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    applied: Mapped[bool] = mapped_column(Boolean)


class MethodResultRow(Base):
    """The result of one identification method of a run (final estimate and trajectories)."""

    __tablename__ = "method_results"
    __table_args__ = (UniqueConstraint("run_id", "label"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"))
    label: Mapped[str] = mapped_column(String(64))
    method: Mapped[str] = mapped_column(String(32))
    params: Mapped[dict[str, Any]] = mapped_column(JSON)
    result: Mapped[dict[str, Any]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime)


class ServerLease(Base):
    """The one server process allowed on this database (see :mod:`thermolab.lab.fleet.lease`)."""

    __tablename__ = "server_lease"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    host: Mapped[str] = mapped_column(String(255))
    pid: Mapped[int] = mapped_column(Integer)
    token: Mapped[str] = mapped_column(String(128))
    acquired_at: Mapped[datetime] = mapped_column(UTCDateTime)
    expires_at: Mapped[datetime] = mapped_column(UTCDateTime)
