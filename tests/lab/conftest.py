"""Fixtures of the lab tests: databases (SQLite and PostgreSQL), labs on a manual clock.

PostgreSQL tests (marker ``postgres``) use the test run's own database
(``THERMOLAB_TEST_POSTGRES_URL``, made by ``tests/conftest.py``); each test gets
a schema of its own there, dropped afterwards, and the tests skip with the
reason when the server cannot be reached.
"""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from argon2 import PasswordHasher
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import OperationalError

from thermolab.lab.clock import ManualClock
from thermolab.lab.config import AccessPolicy, LabConfig, RetentionPolicy, RigConfig
from thermolab.lab.config.smtp import SmtpConfig
from thermolab.lab.db import Database
from thermolab.lab.db.models import Base
from thermolab.lab.fleet.worker_hashes import figures_client
from thermolab.lab.http.app import create_app
from thermolab.lab.rigs.opener import RigOpener
from thermolab.lab.service import Lab

# Argon2 at its cheapest: the tests create many accounts; production uses the defaults.
FAST_HASHER = PasswordHasher(time_cost=1, memory_cost=8, parallelism=1)
PASSWORD = "correct horse"


def postgres_base_url() -> str:
    """The test run's own PostgreSQL database (tests/conftest.py made it)."""
    return os.environ["THERMOLAB_TEST_POSTGRES_URL"]


#: The Redis of the several-workers tests (a broker on loopback here and on CI).
REDIS_URL = os.environ["THERMOLAB_TEST_REDIS_URL"]  # tests/conftest.py: never db 0


@pytest.fixture(scope="session")
def redis_url() -> str:
    """The test Redis's URL; the test is skipped, saying why, where it is unreachable."""
    redis = pytest.importorskip("redis")
    try:
        redis.Redis.from_url(REDIS_URL, socket_connect_timeout=2).ping()
    except redis.RedisError as exc:
        pytest.skip(f"Redis at {REDIS_URL} unreachable: {exc}")
    return REDIS_URL


@pytest.fixture
def redis(redis_url: str) -> Iterator[Any]:
    """A client of the test Redis (the lab's own settings: shared_limits.figures_client)."""
    client = figures_client(redis_url)
    yield client
    client.close()


@pytest.fixture
def prefix(redis: Any) -> Iterator[str]:
    """A lab of its own on the test Redis; its keys are gone after the test."""
    prefix = f"thermolab.test-{uuid.uuid4().hex[:8]}."
    yield prefix
    keys = list(redis.scan_iter(match=prefix + "*"))
    if keys:
        redis.delete(*keys)


@pytest.fixture(scope="session")
def postgres_server() -> str:
    """The PostgreSQL URL, or a skip saying why it cannot be used."""
    url = postgres_base_url()
    engine = create_engine(url, connect_args={"connect_timeout": 3})
    try:
        with engine.connect() as connection:
            connection.execute(text("SELECT 1"))
    except OperationalError as exc:
        reason = str(exc.orig).strip().splitlines()[0] if exc.orig else str(exc)
        pytest.skip(f"PostgreSQL at {make_url(url).render_as_string()} unreachable: {reason}")
    finally:
        engine.dispose()
    return url


@pytest.fixture
def postgres_url(postgres_server: str) -> Iterator[str]:
    """A fresh, empty schema on the test server, as a URL whose search_path points to it."""
    schema = f"thermolab_test_{uuid.uuid4().hex[:12]}"
    admin = create_engine(postgres_server, isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text(f'CREATE SCHEMA "{schema}"'))
    url = make_url(postgres_server).update_query_dict({"options": f"-csearch_path={schema}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


@pytest.fixture(scope="session")
def migrated_sqlite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A SQLite file migrated once per test run, copied by each test that wants a database."""
    path = tmp_path_factory.mktemp("template") / "lab.sqlite3"
    db = Database(f"sqlite:///{path}")
    db.upgrade()
    db.close()
    return path


@pytest.fixture(scope="session")
def migrated_postgres(postgres_server: str) -> Iterator[str]:
    """A schema migrated once per test run (dropped at the end); tests empty it before use."""
    schema = f"thermolab_test_{uuid.uuid4().hex[:12]}"
    admin = create_engine(postgres_server, isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text(f'CREATE SCHEMA "{schema}"'))
    url = make_url(postgres_server).update_query_dict({"options": f"-csearch_path={schema}"})
    rendered = url.render_as_string(hide_password=False)
    db = Database(rendered, pool_size=1, max_overflow=0)
    db.upgrade()
    db.close()
    try:
        yield rendered
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Run a module marked ``sqlite_only`` on SQLite alone: its PostgreSQL twins are deselected.

    Every lab test that takes ``database_url`` runs on both databases unless its module
    says that what it checks does not depend on the database (turn and queue rules, the
    hand-over, marking, the control API's shapes: the same Python over the same store).
    What does depend on it (locks and races, constraints and uniqueness, SQL queries,
    dates, types and blobs, migrations, backups, the API fuzzing) keeps both. The
    PostgreSQL twin of a test costs two to three times its SQLite run (each write is a
    round trip to the server), and the twins of the modules marked so were about a tenth of
    the suite's time (issue #20).
    """
    kept: list[pytest.Item] = []
    dropped: list[pytest.Item] = []
    for item in items:
        callspec = getattr(item, "callspec", None)
        on_postgres = callspec is not None and callspec.params.get("database_url") == "postgres"
        (dropped if on_postgres and item.get_closest_marker("sqlite_only") else kept).append(item)
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = kept


@pytest.fixture(
    params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)],
)
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A migrated, empty database on each backend."""
    if request.param == "sqlite":
        path = tmp_path / "lab.sqlite3"
        shutil.copyfile(request.getfixturevalue("migrated_sqlite"), path)
        return f"sqlite:///{path}"
    url: str = request.getfixturevalue("migrated_postgres")
    empty_postgres(url)
    return url


def empty_postgres(url: str) -> None:
    """Delete every row of the lab's tables in ``url``'s schema and restart their ids.

    DELETE, not TRUNCATE: on tables of a few rows TRUNCATE costs about 0.3 s (new files
    for 34 tables) and DELETE about 25 ms, and some 300 tests a run empty the schema.
    Foreign keys are not checked meanwhile (``session_replication_role``, the test
    server's superuser may set it), so the order of the deletes does not matter.
    """
    engine = create_engine(url)
    try:
        with engine.begin() as connection:
            connection.execute(text("SET LOCAL session_replication_role = replica"))
            for table in Base.metadata.sorted_tables:
                connection.execute(table.delete())
            sequences = connection.execute(
                text(
                    "SELECT sequence_name FROM information_schema.sequences"
                    " WHERE sequence_schema = current_schema()"
                )
            ).scalars()
            for sequence in list(sequences):
                connection.execute(text(f'ALTER SEQUENCE "{sequence}" RESTART'))
    finally:
        engine.dispose()


@pytest.fixture
def sqlite_url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'lab.sqlite3'}"


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock()


def make_config(tmp_path: Path, database_url: str, **rig_options: Any) -> LabConfig:
    """A lab with rigs ``twin`` (and ``other``), the given options applied to ``twin``."""
    twin = replace(RigConfig("twin", "Twin", "sim"), **rig_options)
    other = RigConfig("other", "Other twin", "sim:tclab")
    return LabConfig(data_dir=tmp_path, rigs=(twin, other), database_url=database_url)


LabFactory = Callable[..., Lab]


@pytest.fixture
def make_lab(tmp_path: Path, database_url: str, clock: ManualClock) -> Iterator[LabFactory]:
    """Build and start labs on the test database and the manual clock; closed afterwards."""
    labs: list[Lab] = []

    def build(
        *,
        opener: RigOpener | None = None,
        pool_size: int = 5,
        max_overflow: int = 5,
        retention: RetentionPolicy | None = None,
        access: AccessPolicy | None = None,
        smtp: SmtpConfig | None = None,
        time_zone: str | None = None,
        **rig_options: Any,
    ) -> Lab:
        config = make_config(tmp_path, database_url, **rig_options)
        if retention is not None:
            config = replace(config, retention=retention)
        if access is not None:
            config = replace(config, access=access)
        if smtp is not None:
            config = replace(config, smtp=smtp)
        if time_zone is not None:
            config = replace(config, time_zone=time_zone)
        lab = Lab(
            config,
            clock=clock,
            hasher=FAST_HASHER,
            opener=opener,
            database=Database(database_url, pool_size=pool_size, max_overflow=max_overflow),
        )
        lab.start()
        labs.append(lab)
        return lab

    yield build
    for lab in labs:
        lab.close()


@pytest.fixture
def lab(make_lab: LabFactory) -> Lab:
    return make_lab()


@pytest.fixture
def app_client(lab: Lab) -> Iterator[Callable[..., TestClient]]:
    """Clients of one app (sharing the lab); each keeps its own cookies."""
    app = create_app(lab.config, lab=lab, sweep_interval=None)
    clients: list[TestClient] = []
    with TestClient(app) as first:
        clients.append(first)

        def client(username: str | None = None, **options: Any) -> TestClient:
            new = TestClient(app, **options)
            clients.append(new)
            if username is not None:
                response = new.post(
                    "/api/session", json={"username": username, "password": PASSWORD}
                )
                assert response.status_code == 200, response.text
            return new

        yield client
    for other in clients[1:]:
        other.close()
