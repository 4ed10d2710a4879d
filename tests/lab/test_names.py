"""Names: login names never collide by case or accent; display names keep accents and spaces."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import alembic.command
import pytest
from alembic.config import Config as AlembicConfig
from fastapi.testclient import TestClient
from hypothesis import given
from hypothesis import strategies as st
from sqlalchemy import text

from thermolab.cli import main
from thermolab.errors import ConfigError, ConflictError, InvalidParameterError
from thermolab.lab.accounts.names import normalize_display_name, normalize_username, username_form
from thermolab.lab.db import MIGRATIONS_DIR, Database
from thermolab.lab.service import Lab

from .conftest import PASSWORD

Client = Callable[..., TestClient]


@pytest.mark.parametrize(
    ("given_name", "stored"),
    [
        ("João", "joao"),
        ("JOÃO", "joao"),
        ("joão", "joao"),
        ("Ｊｏａｏ", "joao"),  # full-width letters (NFKC)
        ("Jo\u0061\u0303o", "joao"),  # decomposed accent
        ("Straße", "strasse"),
        ("  maria.silva@maua.br ", "maria.silva@maua.br"),
        ("Ελένη", "ελενη"),
    ],
)
def test_login_names_have_one_normal_form(given_name: str, stored: str) -> None:
    assert normalize_username(given_name) == stored


@pytest.mark.parametrize("bad", ["", "   ", "João da Silva", "-ana", "a" * 65, "ana<1>", "x\u0000"])
def test_bad_login_names_are_refused_saying_what_is_allowed(bad: str) -> None:
    with pytest.raises(InvalidParameterError, match="use 1 to 64 letters"):
        normalize_username(bad)


@given(st.text(min_size=1, max_size=20))
def test_the_normal_form_is_idempotent_and_blind_to_case(name: str) -> None:
    form = username_form(name)
    assert username_form(form) == form
    assert username_form(name.upper()) == username_form(form.upper())


def test_display_names_keep_accents_and_spaces() -> None:
    assert normalize_display_name(" João   da  Silva ") == "João da Silva"
    assert normalize_display_name("Jo\u0061\u0303o") == "João"  # stored composed (NFC)
    assert normalize_display_name("Ana D'Ávila-Souza") == "Ana D'Ávila-Souza"
    for bad in ("", "   ", "<script>", "Ana\u202eevil", "x" * 129):
        with pytest.raises(InvalidParameterError, match="display name"):
            normalize_display_name(bad)


def test_accounts_never_collide_by_case_or_accent(lab: Lab) -> None:
    joao = lab.users.add("João", PASSWORD, "student", display_name="João  da Silva")
    assert (joao.username, joao.display_name) == ("joao", "João da Silva")
    for clash in ("joao", "JOÃO", "jóão", "Ｊｏａｏ"):
        with pytest.raises(ConflictError, match="'joao' already exists"):
            lab.users.add(clash, PASSWORD, "student")
    # Logging in with any spelling of the name reaches the one account.
    for spelling in ("João", "JOAO", "joão"):
        assert lab.users.verify(spelling, PASSWORD).username == "joao"
    assert lab.users.get("JOÃO").display_name == "João da Silva"
    # The database itself refuses a second row with the same normal form.
    from sqlalchemy.exc import IntegrityError

    with pytest.raises(IntegrityError), lab.db.write() as session:
        session.execute(
            text(
                "INSERT INTO users (username, role, password_hash, created_at, "
                "password_changed_at) SELECT username, role, password_hash, created_at, "
                "password_changed_at FROM users WHERE username = 'joao'"
            )
        )


def test_the_api_takes_display_names_and_normalises_login_names(
    lab: Lab, app_client: Client
) -> None:
    lab.users.add("tina", PASSWORD, "teacher", admin=True)
    tina = app_client("tina")
    answer = tina.post(
        "/api/users",
        json={
            "username": "Maria.Conceição",
            "displayName": "Maria da Conceição",
            "password": PASSWORD,
            "role": "student",
        },
    )
    assert answer.status_code == 201, answer.text
    assert answer.json()["username"] == "maria.conceicao"
    assert answer.json()["displayName"] == "Maria da Conceição"
    clash = tina.post(
        "/api/users",
        json={"username": "MARIA.CONCEICAO", "password": PASSWORD, "role": "student"},
    )
    assert (clash.status_code, clash.json()["code"]) == (409, "name_taken")
    bad = tina.post(
        "/api/users",
        json={"username": "ana", "displayName": "<b>", "password": PASSWORD, "role": "student"},
    )
    assert (bad.status_code, bad.json()["code"]) == (422, "invalid_parameter")
    assert "display name" in bad.json()["detail"]
    student = app_client()
    login = student.post("/api/session", json={"username": "Maria.Conceição", "password": PASSWORD})
    assert (login.status_code, login.json()["username"]) == (200, "maria.conceicao")


def test_the_cli_adds_a_display_name(
    database_url: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import io

    monkeypatch.setattr("sys.stdin", io.StringIO(PASSWORD + "\n"))
    status = main(
        [
            "user",
            "add",
            "Zoë",
            "--role",
            "student",
            "--display-name",
            "Zoë Lima",
            "--password-stdin",
            "--database-url",
            database_url,
        ]
    )
    assert status == 0
    assert capsys.readouterr().out.strip() == "added student 'zoe' (Zoë Lima)"


def _at_0005(url: str) -> AlembicConfig:
    config = AlembicConfig()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    return config


def _insert_user(db: Database, name: str) -> None:
    with db.engine.begin() as connection:
        connection.execute(
            text(
                "INSERT INTO users (username, role, password_hash, created_at, "
                "password_changed_at) VALUES (:n, 'student', 'x', :t, :t)"
            ),
            {"n": name, "t": "2026-01-01 00:00:00"},
        )


@pytest.fixture(
    params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)],
)
def fresh_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'fresh.sqlite3'}"
    url: str = request.getfixturevalue("postgres_url")
    return url


def test_migration_0007_normalises_names_and_refuses_collisions(fresh_url: str) -> None:
    db = Database(fresh_url, pool_size=1, max_overflow=0)
    try:
        config = _at_0005(fresh_url)
        with db.engine.begin() as connection:
            config.attributes["connection"] = connection
            alembic.command.upgrade(config, "0005")
        # Rows an older, laxer lab could hold.
        for name in ("ana", "ANA", "Zoë", "bea"):
            _insert_user(db, name)
        with pytest.raises(ConfigError, match=r"'ANA', 'ana' -> 'ana'") as refused:
            db.upgrade()
        assert "Zoë" not in str(refused.value)  # only the clashes are named
        assert db.current_revision() == "0005"
        with db.engine.begin() as connection:
            names = connection.execute(text("SELECT username FROM users")).scalars().all()
            assert sorted(names) == ["ANA", "Zoë", "ana", "bea"]  # nothing changed
            connection.execute(text("DELETE FROM users WHERE username = 'ANA'"))
        db.upgrade()
        assert db.current_revision() == "0023"
        with db.engine.connect() as connection:
            names = connection.execute(text("SELECT username FROM users")).scalars().all()
        assert sorted(names) == ["ana", "bea", "zoe"]
    finally:
        db.close()
