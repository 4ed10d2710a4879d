"""Helpers shared by every test folder, the test run's own database, Hypothesis profiles.

**Services.** ``THERMOLAB_TEST_POSTGRES_URL`` names the PostgreSQL server the
tests may use (default: the ``postgres`` maintenance database on loopback);
each test process (each pytest-xdist worker) creates a database of its own
there, ``thermolab_test_<random>``, points the variable at it for the tests
and the servers they start, and drops it at the end. ``THERMOLAB_TEST_REDIS_URL``
(default ``redis://127.0.0.1:6379/11``, never db 0) is the Redis; every test
and every lab on it has a key prefix of its own. Nothing shared by default is
touched.

**Hypothesis.** The ``ci`` profile (chosen when ``CI`` is set) is derandomized:
the same examples every run, so CI never fails on an example no one saw
before; ``dev`` explores afresh (``--hypothesis-profile`` picks one).
"""

from __future__ import annotations

import os
import time
import uuid
from collections.abc import Callable

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
settings.register_profile("dev", print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

#: The PostgreSQL server the tests may use: a database of the run is made there.
POSTGRES_SERVER_URL = os.environ.get(
    "THERMOLAB_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
)
os.environ.setdefault("THERMOLAB_TEST_REDIS_URL", "redis://127.0.0.1:6379/11")
_RUN_DATABASE: list[str] = []


def pytest_configure(config: pytest.Config) -> None:
    """Compile the source once; make this process's PostgreSQL database before collection."""
    if not hasattr(config, "workerinput"):
        _compile_source()
    if getattr(config.option, "numprocesses", None) and not hasattr(config, "workerinput"):
        return  # the xdist controller runs no test: its workers make their own
    from sqlalchemy import create_engine, text
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import OperationalError

    name = f"thermolab_test_{uuid.uuid4().hex[:12]}"
    admin = create_engine(
        POSTGRES_SERVER_URL, isolation_level="AUTOCOMMIT", connect_args={"connect_timeout": 3}
    )
    try:
        with admin.connect() as connection:
            connection.execute(text(f'CREATE DATABASE "{name}"'))
    except OperationalError:
        return  # unreachable: the PostgreSQL tests skip, saying why
    finally:
        admin.dispose()
    _RUN_DATABASE.append(name)
    url = make_url(POSTGRES_SERVER_URL).set(database=name)
    os.environ["THERMOLAB_TEST_POSTGRES_URL"] = url.render_as_string(hide_password=False)


def _compile_source() -> None:
    # The package is installed editable, so its installer compiled none of it, and where
    # PYTHONDONTWRITEBYTECODE is set (CI's machine) no process caches what it compiles:
    # each server, rig host and CLI process the tests start compiled the ~300 modules
    # anew. py_compile writes the bytecode whatever that variable says (0.6 s, once).
    import compileall
    from pathlib import Path

    import thermolab

    compileall.compile_dir(Path(thermolab.__file__).parent, quiet=2)


def pytest_unconfigure(config: pytest.Config) -> None:
    """Drop this process's database, whatever connection a killed server left behind."""
    if not _RUN_DATABASE:
        return
    from sqlalchemy import create_engine, text

    name = _RUN_DATABASE.pop()
    admin = create_engine(POSTGRES_SERVER_URL, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
    finally:
        admin.dispose()


Poll = Callable[..., bool]


def poll_until(condition: Callable[[], bool], timeout: float = 5.0) -> bool:
    """Wait in real time for something another thread does; return whether it happened.

    For threads that run on their own (a watchdog, a serial emulator, a
    server): simulated time does not pass while this waits, and the condition
    is checked once more at the deadline, so a slow machine only makes the
    wait longer, never the answer different.
    """
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.005)
    return condition()


@pytest.fixture
def wait_until() -> Poll:
    """:func:`poll_until`: ``assert wait_until(lambda: ..., timeout=5.0)``."""
    return poll_until
