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

import asyncio
import contextlib
import os
import time
import uuid
from collections.abc import Callable, Generator, Iterator
from pathlib import Path

import pytest
from _pytest.doctest import DoctestModule
from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
settings.register_profile("dev", print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

#: The PostgreSQL server the tests may use: a database of the run is made there.
POSTGRES_SERVER_URL = os.environ.get(
    "THERMOLAB_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
)
os.environ.setdefault("THERMOLAB_TEST_REDIS_URL", "redis://127.0.0.1:6379/11")
# The suite's servers do not warm the identification methods up as they start (2 s of
# CPU each, for ~150 servers most of which never start a run); tests/client's lab does.
os.environ.setdefault("THERMOLAB_WARM_UP", "0")
_RUN_DATABASE: list[str] = []


def pytest_configure(config: pytest.Config) -> None:
    """Compile the source once; make this process's PostgreSQL database before collection."""
    config.pluginmanager.register(_IdleLoopGuard(), "thermolab-idle-loop-guard")
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

    import thermolab

    compileall.compile_dir(Path(thermolab.__file__).parent, quiet=2)


@pytest.hookimpl(wrapper=True)
def pytest_collect_file(
    file_path: Path, parent: pytest.Collector
) -> Generator[None, list[pytest.Collector], list[pytest.Collector]]:
    """Collect a test module once: not a second time as a module of doctests.

    ``--doctest-modules`` (for the package's examples) also imported every
    ``test_*.py`` and ``conftest.py`` here a second time (the importlib import
    mode makes a new module each time), assertion rewriting included: half of
    the collection's 20 s in each worker. None of them has a doctest; a
    helper module beside them (``web/jsscan.py``) keeps its own.
    """
    collectors = yield
    if file_path.name.startswith("test_") or file_path.name == "conftest.py":
        return [c for c in collectors if not isinstance(c, DoctestModule)]
    return collectors


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """With N workers, put the modules of ``slow`` tests at the head of each worker's share.

    pytest-xdist's ``worksteal`` gives each worker a contiguous Nth of the
    collection and lets an idle worker take the back half of a busy one's queue.
    In collection order the fleet, take-over and browser modules sat at the
    backs of the shares, so the run ended on a few minute-long tests while the
    other workers had nothing left to take. Here every share starts with its
    round of those modules and of the browser's (each kept whole, for its
    module-wide servers; shares balanced on a guess from the marks) and ends
    with short tests, which are what the others take. The order is the
    same in every worker, as xdist requires.
    """
    # The collection that counts is the workers' (xdist's scheduler takes theirs), and a
    # worker's own options say no ``-n``: it reads the count from what xdist tells it.
    worker_input = getattr(config, "workerinput", None)
    workers = worker_input["workercount"] if worker_input is not None else None
    if not isinstance(workers, int) or workers < 2:
        return
    by_module: dict[str, list[pytest.Item]] = {}
    for item in items:
        by_module.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    slow = [m for m, its in by_module.items() if _weight(its)]
    rest = [i for m, its in by_module.items() if m not in slow for i in its]
    heads: list[list[pytest.Item]] = [[] for _ in range(workers)]
    for module in sorted(slow, key=lambda m: -_weight(by_module[m])):  # heaviest first,
        min(heads, key=_weight).extend(by_module[module])  # to the lightest share so far
    # The sizes xdist cuts the collection into: a worker in turn gets an equal part of
    # what is left (xdist/scheduler/worksteal.py, check_schedule).
    left, sizes = len(items), []
    for number in range(workers):
        sizes.append(left // (workers - number))
        left -= sizes[-1]
    ordered: list[pytest.Item] = []
    for head, size in zip(heads, sizes, strict=True):
        fill = max(0, size - len(head))
        ordered += head + rest[:fill]
        rest = rest[fill:]
    items[:] = ordered + rest


def _weight(items: list[pytest.Item]) -> int:
    # A guess at the seconds the tests take, from their marks alone: a ``slow`` test
    # (servers, fleets, long runs) 20 s, any other test in a browser 3 s, the rest none.
    return sum(
        20 if item.get_closest_marker("slow") else 3 if item.get_closest_marker("browser") else 0
        for item in items
    )


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(
    item: pytest.Item, nextitem: pytest.Item | None
) -> Generator[None, object, object]:
    """With ``THERMOLAB_TEST_TIMELINE=FILE``: a line per test (worker, start, end, id).

    Where a run's minutes go across its workers (``.ci/run``'s duration table
    says how long each test took, not when, so not how long a worker idled).
    """
    path = os.environ.get("THERMOLAB_TEST_TIMELINE")
    began = time.time()
    result = yield
    if path:
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        with open(path, "a", encoding="utf-8") as timeline:
            timeline.write(f"{worker}\t{began:.3f}\t{time.time():.3f}\t{item.nodeid}\n")
    return result


class _IdleLoopGuard:
    """Every test, the package's doctests included, runs as if no event loop ran here.

    A plugin of its own, registered at configure time: a conftest's hooks reach
    only the tests beside it, not ``src/thermolab``'s doctests. See
    :func:`_no_idle_loop`.
    """

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_setup(self, item: pytest.Item) -> Generator[None, None, None]:
        with _no_idle_loop(item):
            return (yield)

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_call(self, item: pytest.Item) -> Generator[None, None, None]:
        with _no_idle_loop(item):
            return (yield)


@contextlib.contextmanager
def _no_idle_loop(item: pytest.Item) -> Iterator[None]:
    # The browser tests' Playwright (session-wide, tests/web/conftest.py) keeps its event
    # loop "running" in the worker's main thread between its calls, while its greenlet
    # waits: a later test's asyncio.run() then raised "cannot be called from a running
    # event loop" (the order of the run decides which tests come after a browser test).
    # Nothing runs that loop during another test, so that test sees none; a browser
    # test keeps it, and teardown (which may close Playwright) is left alone.
    idle = asyncio.events._get_running_loop()
    if idle is None or item.get_closest_marker("browser") or item.nodeid.startswith("tests/web/"):
        yield
        return
    asyncio.events._set_running_loop(None)
    try:
        yield
    finally:
        asyncio.events._set_running_loop(idle)


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
