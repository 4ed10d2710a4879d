"""A lab's backup: one archive holding its database and data folder, and its restore.

:func:`make_backup` copies a running lab consistently: a SQLite database
through SQLite's online backup API (readers and the writer go on; the copy is
one transaction's view), a PostgreSQL one through ``pg_dump`` (one snapshot),
and every other file of the data folder (the run records, whatever secrets or
pictures an operator keeps there) beside it. The archive is a gzip'd tar with
``manifest.json`` first: the archive format, ThermoLab's version, the schema
revision, the backend, the date, and each member's size and SHA-256.

:func:`restore_backup` checks every checksum before it writes anything, then
brings the backup back into an empty data folder (and, for PostgreSQL, an
empty database through ``psql``). It refuses a backup whose schema revision
this release does not know (a backup from a newer ThermoLab), a damaged
archive and a target that is not empty; a backup from an older release is
restored and then upgraded by the migrations, as ``thermolab serve`` would.

Examples
--------
>>> import tempfile
>>> from thermolab.lab.config import default_config
>>> from thermolab.lab.db import Database
>>> with tempfile.TemporaryDirectory() as tmp:
...     config = default_config(Path(tmp, "lab"))
...     Database(config.database).upgrade()
...     made = make_backup(config, Path(tmp, "lab.tar.gz"))
...     back = restore_backup(Path(tmp, "lab.tar.gz"), default_config(Path(tmp, "new")))
>>> made.revision == back.revision == head_revision()
True
"""

from __future__ import annotations

import datetime as dt
import hashlib
import io
import json
import os
import re
import shutil
import sqlite3
import subprocess
import tarfile
import tempfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from sqlalchemy.engine import make_url

from thermolab import __version__
from thermolab.errors import ConfigError, InvalidDataError
from thermolab.lab.config import LabConfig
from thermolab.lab.db import MIGRATIONS_DIR, Database

__all__ = [
    "ARCHIVE_FORMAT",
    "BackupManifest",
    "head_revision",
    "known_revisions",
    "make_backup",
    "read_manifest",
    "restore_backup",
]

ARCHIVE_FORMAT = 1
"""The archive layout's version; a reader refuses formats it does not know."""
_MANIFEST = "manifest.json"
_SQLITE_MEMBER = "database/thermolab.sqlite3"
_POSTGRES_MEMBER = "database/thermolab.sql"
_DATA_PREFIX = "data/"
_SQLITE_SIDE_FILES = ("-wal", "-shm", "-journal")
_CREATE_SCHEMA = re.compile(r"^CREATE SCHEMA (\S+);$")


@dataclass(frozen=True, slots=True)
class BackupManifest:
    """What a backup archive holds.

    Attributes
    ----------
    version : str
        ThermoLab's version that made it.
    revision : str or None
        The database's schema revision (Alembic), ``None`` for an empty database.
    backend : str
        ``sqlite`` or ``postgresql``.
    created : str
        When it was made (UTC, ISO 8601).
    files : dict
        Each member's name to its ``{"size": bytes, "sha256": hex}``.
    format : int
        The archive layout (:data:`ARCHIVE_FORMAT`).
    """

    version: str
    revision: str | None
    backend: str
    created: str
    files: dict[str, dict[str, Any]] = field(default_factory=dict)
    format: int = ARCHIVE_FORMAT

    def to_dict(self) -> dict[str, Any]:
        """The manifest as JSON-ready data."""
        return {
            "format": self.format,
            "version": self.version,
            "revision": self.revision,
            "backend": self.backend,
            "created": self.created,
            "files": self.files,
        }


def known_revisions() -> list[str]:
    """Every schema revision this release ships, oldest first."""
    from alembic.config import Config
    from alembic.script import ScriptDirectory

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    script = ScriptDirectory.from_config(config)
    return [rev.revision for rev in reversed(list(script.walk_revisions()))]


def head_revision() -> str:
    """The schema revision of this release."""
    return known_revisions()[-1]


def make_backup(config: LabConfig, archive: Path) -> BackupManifest:
    """Copy the lab of ``config`` (it may be running) into the archive ``archive``.

    The archive is written beside its final name and renamed when complete,
    readable by its owner only (it holds the password hashes and secrets).

    Raises
    ------
    ConfigError
        If the database cannot be read, or it is PostgreSQL and ``pg_dump`` is
        not installed.
    """
    archive = Path(archive).resolve()
    url = make_url(config.database)
    if url.get_backend_name() == "sqlite" and not _sqlite_path(config.database).is_file():
        raise ConfigError(
            f"no lab database at {_sqlite_path(config.database)}; give the lab's --data-dir"
        )
    db = Database(config.database, pool_size=1, max_overflow=0)
    try:
        revision = db.current_revision()
        backend = db.backend
        with tempfile.TemporaryDirectory(prefix="thermolab-backup-") as tmp:
            staging = Path(tmp)
            if backend == "sqlite":
                _sqlite_copy(_sqlite_path(db.url), staging / _SQLITE_MEMBER)
            else:
                _pg_dump(db.url, staging / _POSTGRES_MEMBER)
            for path in _data_files(config, exclude=archive):
                target = staging / _DATA_PREFIX / path.relative_to(config.data_dir)
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, target)
            members = sorted(p for p in staging.rglob("*") if p.is_file())
            manifest = BackupManifest(
                version=__version__,
                revision=revision,
                backend=backend,
                created=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
                files={
                    p.relative_to(staging).as_posix(): {
                        "size": p.stat().st_size,
                        "sha256": _sha256(p),
                    }
                    for p in members
                },
            )
            partial = archive.with_name(archive.name + ".partial")
            archive.parent.mkdir(parents=True, exist_ok=True)
            descriptor = os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            with os.fdopen(descriptor, "wb") as raw, tarfile.open(fileobj=raw, mode="w:gz") as tar:
                body = json.dumps(manifest.to_dict(), indent=2).encode()
                info = tarfile.TarInfo(_MANIFEST)
                info.size, info.mode = len(body), 0o600
                tar.addfile(info, io.BytesIO(body))
                for path in members:
                    tar.add(path, arcname=path.relative_to(staging).as_posix(), recursive=False)
            partial.replace(archive)
    finally:
        db.close()
    return manifest


def read_manifest(archive: Path) -> BackupManifest:
    """Read an archive's manifest (nothing else is checked).

    Raises
    ------
    InvalidDataError
        If the file is not a ThermoLab backup or its format is unknown.
    """
    try:
        with tarfile.open(archive, mode="r:gz") as tar:
            member = tar.extractfile(_MANIFEST)
            data = json.loads(member.read()) if member is not None else None
    except (OSError, tarfile.TarError, KeyError, ValueError):
        raise InvalidDataError(
            f"{archive} is not a ThermoLab backup (no readable manifest)"
        ) from None
    if not isinstance(data, dict) or data.get("format") != ARCHIVE_FORMAT:
        found = data.get("format") if isinstance(data, dict) else None
        raise InvalidDataError(
            f"{archive} is a backup of format {found!r}; "
            f"this ThermoLab reads format {ARCHIVE_FORMAT}"
        )
    return BackupManifest(
        version=str(data["version"]),
        revision=data["revision"],
        backend=str(data["backend"]),
        created=str(data["created"]),
        files=dict(data["files"]),
    )


def restore_backup(archive: Path, config: LabConfig) -> BackupManifest:
    """Bring the backup ``archive`` back into the empty lab of ``config``.

    Raises
    ------
    InvalidDataError
        If the archive is damaged (a checksum or a member differs from the manifest).
    ConfigError
        If the backup's schema is newer than this release's, its database kind
        differs from the target's, or the data folder or database is not empty.
    """
    manifest = read_manifest(archive)
    revisions = known_revisions()
    if manifest.revision is not None and manifest.revision not in revisions:
        raise ConfigError(
            f"the backup was made by ThermoLab {manifest.version} at schema revision "
            f"{manifest.revision}, which this ThermoLab {__version__} (revision {revisions[-1]}) "
            f"does not know; restore it with ThermoLab {manifest.version} or newer"
        )
    data_dir = config.data_dir
    if data_dir.exists() and any(data_dir.iterdir()):
        raise ConfigError(f"the data folder {data_dir} is not empty; restore into an empty one")
    url = config.database
    backend = make_url(url).get_backend_name()
    if backend != manifest.backend:
        raise ConfigError(
            f"the backup holds a {manifest.backend} database and the target is {backend}; "
            "give the matching --database-url"
        )
    if backend == "sqlite":
        if _sqlite_path(url).exists():
            raise ConfigError(
                f"the database {_sqlite_path(url)} exists; restore into an empty place"
            )
    else:
        db = Database(url, pool_size=1, max_overflow=0)
        try:
            if db.table_names():
                raise ConfigError(
                    f"the database {db.display_url} is not empty; restore into an empty one"
                )
        finally:
            db.close()
    with tempfile.TemporaryDirectory(prefix="thermolab-restore-") as tmp:
        staging = Path(tmp)
        _extract_checked(archive, manifest, staging)
        data_dir.mkdir(mode=0o700, parents=True, exist_ok=True)
        data = staging / _DATA_PREFIX
        if data.is_dir():
            shutil.copytree(data, data_dir, dirs_exist_ok=True)
        if manifest.backend == "sqlite":
            _sqlite_path(url).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(staging / _SQLITE_MEMBER, _sqlite_path(url))
        else:
            _psql(url, staging / _POSTGRES_MEMBER)
    db = Database(config.database, pool_size=1, max_overflow=0)
    try:
        db.upgrade()  # a backup from an older release meets this release's schema
    finally:
        db.close()
    return manifest


def _extract_checked(archive: Path, manifest: BackupManifest, staging: Path) -> None:
    expected = dict(manifest.files)
    with tarfile.open(archive, mode="r:gz") as tar:
        for member in tar:
            if member.name == _MANIFEST:
                continue
            name = PurePosixPath(member.name)
            if member.name not in expected or not member.isfile() or ".." in name.parts:
                raise InvalidDataError(f"{archive}: unexpected member {member.name!r}")
            source = tar.extractfile(member)
            assert source is not None
            target = staging / name
            target.parent.mkdir(parents=True, exist_ok=True)
            digest = hashlib.sha256()
            with target.open("wb") as out:
                while chunk := source.read(1 << 20):
                    digest.update(chunk)
                    out.write(chunk)
            if digest.hexdigest() != expected.pop(member.name)["sha256"]:
                raise InvalidDataError(
                    f"{archive}: {member.name} is damaged (its checksum differs)"
                )
    if expected:
        raise InvalidDataError(f"{archive}: missing {', '.join(sorted(expected))}")


def _data_files(config: LabConfig, *, exclude: Path) -> list[Path]:
    data_dir = config.data_dir
    if not data_dir.is_dir():
        return []
    skipped = {exclude, exclude.with_name(exclude.name + ".partial")}
    url = make_url(config.database)
    if url.get_backend_name() == "sqlite" and url.database:
        database = Path(url.database).resolve()
        skipped |= {database, *(Path(f"{database}{end}") for end in _SQLITE_SIDE_FILES)}
    return sorted(
        path
        for path in data_dir.rglob("*")
        if path.is_file() and not path.is_symlink() and path.resolve() not in skipped
    )


def _sqlite_path(url: str) -> Path:
    database = make_url(url).database
    if not database or database == ":memory:":
        raise ConfigError("an in-memory database cannot be backed up or restored")
    return Path(database)


def _sqlite_copy(source: Path, target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    # In one step: a read transaction for the whole copy (in WAL mode the lab's
    # writer goes on), so the copy is one consistent state of the database.
    src = sqlite3.connect(source, timeout=30)
    dst = sqlite3.connect(target)
    try:
        src.backup(dst)
    finally:
        dst.close()
        src.close()


def _libpq_url(url: str) -> str:
    return make_url(url).set(drivername="postgresql").render_as_string(hide_password=False)


def _postgres_tool(name: str) -> str:
    tool = shutil.which(name)
    if tool is None:
        raise ConfigError(
            f"{name} is not on PATH: install PostgreSQL's client tools "
            "(Debian: apt install postgresql-client) to back up or restore a PostgreSQL lab"
        )
    return tool


def _pg_dump(url: str, target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    schema = _current_schema(url)
    command = [
        _postgres_tool("pg_dump"),
        "--no-owner",
        "--no-privileges",
        f"--schema={schema}",
        f"--file={target}",
        f"--dbname={_libpq_url(url)}",
    ]
    _run(command, "pg_dump")


def _psql(url: str, script: Path) -> None:
    # pg_dump --schema writes CREATE SCHEMA; an empty database already has "public".
    existing = _schemas(url)
    fitted = script.with_suffix(".restore.sql")
    with script.open(encoding="utf-8") as source, fitted.open("w", encoding="utf-8") as out:
        for line in source:
            created = _CREATE_SCHEMA.match(line)
            if created is None or created.group(1).strip('"') not in existing:
                out.write(line)
    script = fitted
    command = [
        _postgres_tool("psql"),
        "--quiet",
        "--no-psqlrc",
        "--single-transaction",
        "--set=ON_ERROR_STOP=1",
        f"--file={script}",
        f"--dbname={_libpq_url(url)}",
    ]
    _run(command, "psql")


def _schemas(url: str) -> set[str]:
    from sqlalchemy import text

    db = Database(url, pool_size=1, max_overflow=0)
    try:
        with db.read() as session:
            return set(session.scalars(text("SELECT nspname FROM pg_namespace")))
    finally:
        db.close()


def _current_schema(url: str) -> str:
    from sqlalchemy import text

    db = Database(url, pool_size=1, max_overflow=0)
    try:
        with db.read() as session:
            return str(session.execute(text("SELECT current_schema()")).scalar_one())
    finally:
        db.close()


def _run(command: list[str], name: str) -> None:
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        lines = (done.stderr or done.stdout).strip().splitlines()
        raise ConfigError(f"{name} failed: {lines[0] if lines else f'exit {done.returncode}'}")


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as file:
        while chunk := file.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()
