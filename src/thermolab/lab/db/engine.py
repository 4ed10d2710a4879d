"""The lab's database: engine set-up for SQLite and PostgreSQL, transactions, migrations.

Two kinds of transaction:

* :meth:`Database.read` — a plain transaction for queries.
* :meth:`Database.write` — a transaction that is the only writer from its
  first statement: ``BEGIN IMMEDIATE`` on SQLite (the database-wide write
  lock is taken at once, so two writers never both read a stale state and
  then collide), and on PostgreSQL an ordinary transaction in which the caller
  locks the row it decides on with ``SELECT ... FOR UPDATE``
  (:meth:`Database.lock_rig`).

SQLite runs in WAL mode (readers never block the writer), with foreign keys
on and a busy timeout long enough that a queue of writers waits instead of
failing. The schema is created and upgraded by the Alembic migrations shipped
in the package, run programmatically (:meth:`Database.upgrade`).
"""

from __future__ import annotations

import contextlib
import sqlite3
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import alembic.command
from alembic.config import Config
from sqlalchemy import Connection, Engine, create_engine, event, inspect, select
from sqlalchemy.engine import make_url
from sqlalchemy.engine.interfaces import DBAPIConnection
from sqlalchemy.exc import ArgumentError, OperationalError
from sqlalchemy.orm import Session, sessionmaker
from sqlalchemy.pool import ConnectionPoolEntry

from thermolab.errors import ConfigError, NotFoundError
from thermolab.lab.db.models import RigRow

__all__ = ["MIGRATIONS_DIR", "Database", "normalize_database_url"]

MIGRATIONS_DIR = Path(__file__).with_name("migrations")

# Seconds a SQLite writer waits for the write lock before giving up. A class of
# students all pressing "ask for control" at once queues behind one another.
SQLITE_BUSY_TIMEOUT = 30.0
_IMMEDIATE = "thermolab_immediate"
# Seconds a process waits for another one's migrations (a large database's take minutes).
UPGRADE_WAIT = 600.0


def normalize_database_url(url: str) -> str:
    """Return ``url`` with the driver ThermoLab uses made explicit.

    ``postgresql://`` and ``postgres://`` become ``postgresql+psycopg://``
    (psycopg 3); other URLs are returned unchanged.

    Raises
    ------
    ConfigError
        If the URL cannot be parsed or names a database ThermoLab does not support.

    Examples
    --------
    >>> normalize_database_url("postgresql://lab@db/thermolab")
    'postgresql+psycopg://lab@db/thermolab'
    >>> normalize_database_url("sqlite:////srv/lab/thermolab.sqlite3")
    'sqlite:////srv/lab/thermolab.sqlite3'
    """
    try:
        parsed = make_url(url)
    except ArgumentError:
        raise ConfigError(
            f"database URL {url!r} is not understood; use sqlite:///PATH or "
            "postgresql+psycopg://USER@HOST/DB"
        ) from None
    backend, _, driver = parsed.drivername.partition("+")
    if backend == "postgres":
        backend = "postgresql"
    if backend == "postgresql" and driver in ("", "psycopg"):
        return parsed.set(drivername="postgresql+psycopg").render_as_string(hide_password=False)
    if backend == "sqlite" and driver in ("", "pysqlite"):
        return url
    raise ConfigError(
        f"database {parsed.drivername!r} is not supported; use sqlite:///PATH or "
        "postgresql+psycopg://USER@HOST/DB"
    )


class Database:
    """An engine with the lab's transaction discipline.

    Parameters
    ----------
    url : str
        SQLAlchemy URL: ``sqlite:///PATH`` or ``postgresql+psycopg://...``.
    pool_size : int
        Connections kept open.
    max_overflow : int
        Further connections opened on demand (and closed when returned).

    Raises
    ------
    ConfigError
        If the URL is not supported.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     db = Database(f"sqlite:///{tmp}/lab.sqlite3")
    ...     db.upgrade()
    ...     tables = db.table_names()
    ...     db.close()
    >>> "control_sessions" in tables
    True
    """

    def __init__(self, url: str, *, pool_size: int = 10, max_overflow: int = 20) -> None:
        self.url = normalize_database_url(url)
        parsed = make_url(self.url)
        self.backend = parsed.get_backend_name()
        if self.backend == "sqlite":
            if parsed.database and parsed.database != ":memory:":
                Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
            engine = create_engine(
                self.url,
                connect_args={"timeout": SQLITE_BUSY_TIMEOUT, "check_same_thread": False},
                pool_size=pool_size,
                max_overflow=max_overflow,
            )
            event.listen(engine, "connect", _sqlite_on_connect)
            event.listen(engine, "begin", _sqlite_on_begin)
        else:
            engine = create_engine(
                self.url, pool_size=pool_size, max_overflow=max_overflow, pool_pre_ping=True
            )
        self.engine: Engine = engine
        self._closed = False
        # A connection a thread still holds when the database is closed goes back
        # to the disposed pool later; close it there, rather than leaving it to the
        # garbage collector (psycopg warns about a connection deleted while open).
        event.listen(engine, "checkin", self._close_late_checkin)
        self._sqlite_writer: contextlib.AbstractContextManager[object] = (
            threading.RLock() if self.backend == "sqlite" else contextlib.nullcontext()
        )
        self._reader = sessionmaker(engine, expire_on_commit=False)
        self._writer = sessionmaker(
            engine.execution_options(**{_IMMEDIATE: True}), expire_on_commit=False
        )

    @contextlib.contextmanager
    def read(self) -> Iterator[Session]:
        """Open a session for queries (objects read stay usable after the block).

        Yields
        ------
        Session
        """
        with self._reader() as session, session.begin():
            yield session

    @contextlib.contextmanager
    def write(self) -> Iterator[Session]:
        """Open a writing transaction; committed when the block ends, rolled back on error.

        Yields
        ------
        Session
        """
        # SQLite has one writer at a time. Writers of this process queue on a lock,
        # which hands over at once, instead of in SQLite's busy handler, which
        # sleeps up to 100 ms between tries; BEGIN IMMEDIATE still excludes other
        # processes (the command line).
        with self._sqlite_writer, self._writer() as session, session.begin():
            yield session

    def lock_rig(self, session: Session, rig_id: str) -> RigRow:
        """Lock and return a rig's row for the rest of a :meth:`write` transaction.

        On PostgreSQL this is ``SELECT ... FOR UPDATE``: every transaction that
        decides on the rig's controller or queue passes through this row, one
        at a time. On SQLite the write transaction already holds the database
        write lock.

        Raises
        ------
        NotFoundError
            If there is no such rig.
        """
        rig = session.scalars(
            select(RigRow).where(RigRow.id == rig_id).with_for_update()
        ).one_or_none()
        if rig is None:
            raise NotFoundError(f"no rig called {rig_id!r}")
        return rig

    def upgrade(self) -> None:
        """Create or upgrade the schema to the newest migration (idempotent).

        Raises
        ------
        ConfigError
            If the database cannot be reached (the message says where and why).
        """
        config = Config()
        config.set_main_option("script_location", str(MIGRATIONS_DIR))
        # One migrator at a time: on SQLite the write lock is taken before the
        # version is read (BEGIN IMMEDIATE), so a command started while the server
        # makes or migrates the schema waits for it (up to UPGRADE_WAIT), then finds
        # the schema at head, instead of failing either side with "database is
        # locked". PostgreSQL's DDL takes its locks as it goes, in one transaction.
        engine = self.engine.execution_options(**{_IMMEDIATE: True})
        try:
            with self._sqlite_writer, engine.connect() as connection:
                # SQLite alters a table by copying it and dropping the old one; with
                # foreign keys on, that drop deleted or emptied the rows pointing at it
                # (a user's tokens, the user of each turn). SQLite's own recipe: keys
                # off for the change, then a check before the commit.
                _sqlite_pragmas(connection, UPGRADE_WAIT, foreign_keys=False)
                try:
                    with connection.begin():
                        config.attributes["connection"] = connection
                        alembic.command.upgrade(config, "head")
                        if self.backend == "sqlite":
                            broken = connection.exec_driver_sql("PRAGMA foreign_key_check").all()
                            if broken:
                                raise ConfigError(
                                    f"the migrations left {len(broken)} rows pointing at "
                                    f"nothing (first: {tuple(broken[0])}); nothing was changed"
                                )
                finally:
                    _sqlite_pragmas(connection, SQLITE_BUSY_TIMEOUT, foreign_keys=True)
        except OperationalError as exc:
            raise ConfigError(
                f"cannot open the database {self.display_url}: {_first_line(exc)}"
            ) from None

    def current_revision(self) -> str | None:
        """Return the migration revision the database is at (``None`` if empty)."""
        from alembic.runtime.migration import MigrationContext

        with self.engine.connect() as connection:
            return MigrationContext.configure(connection).get_current_revision()

    def table_names(self) -> list[str]:
        """Return the names of the tables in the database, sorted."""
        return sorted(inspect(self.engine).get_table_names())

    @property
    def display_url(self) -> str:
        """The URL with any password hidden, for messages and logs."""
        return make_url(self.url).render_as_string(hide_password=True)

    def close(self) -> None:
        """Close every pooled connection (and any still in use, when it comes back)."""
        self._closed = True
        self.engine.dispose()

    def _close_late_checkin(
        self, dbapi_connection: DBAPIConnection | None, record: ConnectionPoolEntry
    ) -> None:
        if self._closed and dbapi_connection is not None:
            record.invalidate()

    def __repr__(self) -> str:
        return f"Database({self.display_url!r})"


def _first_line(exc: BaseException) -> str:
    text = str(getattr(exc, "orig", None) or exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _sqlite_on_connect(dbapi_connection: DBAPIConnection, record: ConnectionPoolEntry) -> None:
    assert isinstance(dbapi_connection, sqlite3.Connection)
    # Take BEGIN away from the driver so that it can be BEGIN IMMEDIATE where needed.
    dbapi_connection.isolation_level = None
    cursor = dbapi_connection.cursor()
    try:
        _wal(cursor)
        # NORMAL is durable across a crash of the process in WAL mode (only an OS
        # crash may lose the last transactions) and much faster than FULL.
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute(f"PRAGMA busy_timeout={int(SQLITE_BUSY_TIMEOUT * 1000)}")
    finally:
        cursor.close()


def _wal(cursor: sqlite3.Cursor) -> None:
    """Put the database in WAL mode, waiting out another connection that does it too.

    Two connections opening a new database both read its header, then both ask for
    the exclusive lock that changes its journal mode: SQLite refuses one at once,
    with no busy wait (the wait could deadlock), and a command started with the
    server failed with "database is locked" on a loaded machine.
    """
    deadline = time.monotonic() + SQLITE_BUSY_TIMEOUT
    while True:
        try:
            cursor.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.02)  # real time: the other connection's change takes a moment


def _sqlite_pragmas(connection: Connection, busy_timeout: float, *, foreign_keys: bool) -> None:
    # On the driver's connection: through SQLAlchemy the PRAGMA would begin a transaction
    # (and foreign_keys cannot change inside one).
    raw = connection.connection.driver_connection
    if isinstance(raw, sqlite3.Connection):
        raw.execute(f"PRAGMA busy_timeout={int(busy_timeout * 1000)}")
        raw.execute(f"PRAGMA foreign_keys={'ON' if foreign_keys else 'OFF'}")


def _sqlite_on_begin(connection: Connection) -> None:
    options: dict[str, Any] = dict(connection.get_execution_options())
    connection.exec_driver_sql("BEGIN IMMEDIATE" if options.get(_IMMEDIATE) else "BEGIN")
