"""``thermolab backup`` / ``restore``: a running lab copied into one archive and back."""

from __future__ import annotations

import io
import json
import math
import shutil
import tarfile
import uuid
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url

from thermolab.cli import main
from thermolab.errors import ConfigError
from thermolab.lab.accounts.users import UserService
from thermolab.lab.clock import ManualClock
from thermolab.lab.config import default_config
from thermolab.lab.db import Database
from thermolab.lab.http.app import create_app
from thermolab.lab.operations.backup import (
    head_revision,
    make_backup,
    read_manifest,
    restore_backup,
)
from thermolab.lab.service import Lab

from .conftest import FAST_HASHER, PASSWORD, LabFactory, make_config
from .test_runs import (
    StepClock,
    lab_request,
    person,
    stored_samples,
    twin_lab,
    until,
)


@pytest.fixture
def step_clock() -> Iterator[StepClock]:
    clock = StepClock()
    yield clock
    clock.allow(math.inf)  # never leave a run blocked behind a test


def answers(lab: Lab, run_id: int) -> dict[str, Any]:
    """What the API says about the lab, a teacher reading."""
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        client.post("/api/session", json={"username": "tina", "password": PASSWORD})
        run = client.get(f"/api/runs/{run_id}").json()
        for key in ("status", "endReason", "ended", "endedAt", "samplesTaken", "results"):
            run.pop(key, None)  # a restart interrupts the run going; its live estimates go

        return {
            "run": run,
            "samples": client.get(f"/api/runs/{run_id}/samples.csv").text,
            "runs": [r["id"] for r in client.get("/api/runs").json()],
            "me": client.get("/api/session").json(),
        }


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_a_backup_taken_mid_run_restores_to_a_lab_that_answers_the_same(
    make_lab: LabFactory, tmp_path: Path, step_clock: StepClock
) -> None:
    lab = twin_lab(make_lab, step_clock)
    ana, _ = person(lab, "ana"), person(lab, "tina", "teacher")
    secret = tmp_path / "secrets" / "rig-host.key"
    secret.parent.mkdir()
    secret.write_bytes(b"not really a key\n")
    lab.access.request_control("twin", ana)
    run = lab.runs.start("twin", ana, lab_request(samples=200))
    step_clock.allow(49.0)
    until(lambda: stored_samples(lab, run.id) == 50)
    archive = tmp_path.parent / f"{tmp_path.name}-backup.tar.gz"
    manifest = make_backup(lab.config, archive)  # the run goes on meanwhile
    assert stored_samples(lab, run.id) == 50  # the twin's clock is held at 49 s
    before = answers(lab, run.id)
    step_clock.allow(math.inf)

    assert (manifest.revision, manifest.backend) == (head_revision(), "sqlite")
    assert set(manifest.files) == {"database/thermolab.sqlite3", "data/secrets/rig-host.key"}
    assert read_manifest(archive) == manifest
    assert archive.stat().st_mode & 0o077 == 0

    fresh = tmp_path.parent / f"{tmp_path.name}-restored"
    url = f"sqlite:///{fresh / 'thermolab.sqlite3'}"
    restore_backup(archive, default_config(fresh))
    assert (fresh / "secrets" / "rig-host.key").read_bytes() == b"not really a key\n"
    restored = Lab(
        make_config(fresh, url),
        clock=ManualClock(),
        hasher=FAST_HASHER,
        database=Database(url, pool_size=2, max_overflow=2),
    )
    restored.start()
    try:
        assert answers(restored, run.id) == before
    finally:
        restored.close()


def test_restore_refuses_a_filled_target_a_newer_backup_and_a_damaged_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lab_dir, archive = tmp_path / "lab", tmp_path / "lab.tar.gz"
    assert main(["--data-dir", str(lab_dir), "backup", str(archive)]) == 1
    assert "no lab database at" in capsys.readouterr().err
    assert not (lab_dir / "thermolab.sqlite3").exists()
    Database(default_config(lab_dir).database).upgrade()
    assert main(["--data-dir", str(lab_dir), "backup", str(archive)]) == 0
    assert "backed up the lab" in capsys.readouterr().out

    assert main(["--data-dir", str(lab_dir), "restore", str(archive)]) == 1
    assert capsys.readouterr().err.strip().endswith("is not empty; restore into an empty one")

    def rewrite(name: str, change: Any) -> Path:
        target = tmp_path / name
        with tarfile.open(archive) as source, tarfile.open(target, "w:gz") as out:
            for member in source:
                data = source.extractfile(member).read()  # type: ignore[union-attr]
                data = change(member.name, data)
                member.size = len(data)
                out.addfile(member, io.BytesIO(data))
        return target

    def newer(name: str, data: bytes) -> bytes:
        if name != "manifest.json":
            return data
        manifest = json.loads(data)
        manifest.update(version="9.0.0", revision="v9999_future")
        return json.dumps(manifest).encode()

    def damaged(name: str, data: bytes) -> bytes:
        return data[:-1] + b"!" if name.startswith("database/") else data

    for name, change, said in [
        ("newer.tar.gz", newer, "made by ThermoLab 9.0.0 at schema revision v9999_future"),
        ("damaged.tar.gz", damaged, "thermolab.sqlite3 is damaged (its checksum differs)"),
    ]:
        target = tmp_path / f"new-{name}"
        assert main(["--data-dir", str(target), "restore", str(rewrite(name, change))]) == 1
        err = capsys.readouterr().err
        assert said in err
        assert len(err.strip().splitlines()) == 1, err
        assert not (target / "thermolab.sqlite3").exists()

    assert main(["--data-dir", str(tmp_path / "fresh"), "restore", str(archive)]) == 0
    assert (
        Database(default_config(tmp_path / "fresh").database).current_revision() == head_revision()
    )


@pytest.mark.postgres
def test_a_postgresql_lab_is_dumped_and_restored_into_an_empty_database(
    postgres_url: str, postgres_server: str, tmp_path: Path
) -> None:
    if shutil.which("pg_dump") is None or shutil.which("psql") is None:
        pytest.skip("PostgreSQL's client tools (pg_dump, psql) are not on PATH")
    db = Database(postgres_url, pool_size=1, max_overflow=0)
    db.upgrade()
    UserService(db, ManualClock(), FAST_HASHER).add("tina", PASSWORD, "teacher")
    db.close()
    source = replace(default_config(tmp_path / "lab"), database_url=postgres_url)
    manifest = make_backup(source, tmp_path / "lab.tar.gz")
    assert (manifest.backend, list(manifest.files)) == ("postgresql", ["database/thermolab.sql"])

    name = f"thermolab_restore_{uuid.uuid4().hex[:8]}"
    admin = create_engine(postgres_server, isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text(f'CREATE DATABASE "{name}"'))
    target_url = make_url(postgres_url).set(database=name).render_as_string(hide_password=False)
    try:
        target = replace(default_config(tmp_path / "new"), database_url=target_url)
        restore_backup(tmp_path / "lab.tar.gz", target)
        with pytest.raises(ConfigError, match="is not empty"):
            restore_backup(tmp_path / "lab.tar.gz", replace(target, data_dir=tmp_path / "n2"))
        restored = Database(target_url, pool_size=1, max_overflow=0)
        users = UserService(restored, ManualClock(), FAST_HASHER).list()
        restored.close()
        assert [(u.username, u.role.value) for u in users] == [("tina", "teacher")]
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()
