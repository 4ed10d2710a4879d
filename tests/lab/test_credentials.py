"""Credentials never weak, never echoed; WebSocket frames capped before they are read (#25)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from fastapi.testclient import TestClient

from thermolab.errors import InvalidParameterError
from thermolab.lab.accounts.security import validate_password

Client = Callable[..., TestClient]
SECRET = "SuperSecret-123"


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


@pytest.mark.parametrize(
    "password",
    [
        "123456789012",
        "qwertyuiopas",
        "aaaaaaaaaaaa",
        "thermolab123",
        "1q2w3e4r5t6y",
        "abcdefghijkl",
    ],
)
def test_common_twelve_character_passwords_are_refused_without_being_repeated(
    password: str,
) -> None:
    with pytest.raises(InvalidParameterError) as refused:
        validate_password(password, "ana")
    assert password not in str(refused.value)


@pytest.mark.parametrize(
    "password", ["correct horse", "a long caio secret", "pw-ana-123-xyz", "Tr0ub4dor&3x!"]
)
def test_passwords_that_are_not_common_patterns_are_kept(password: str) -> None:
    assert validate_password(password, "ana") == password


@pytest.mark.parametrize(
    ("content", "kind"),
    [
        (f"username=ana&password={SECRET}", "application/x-www-form-urlencoded"),
        (f'[{{"username": "ana", "password": "{SECRET}"}}]', "application/json"),
        (f'{{"username": "ana", "password": ["{SECRET}"]}}', "application/json"),
        (f'{{"username": ["{SECRET}"], "password": "{SECRET}"}}', "application/json"),
    ],
    ids=["form", "a list of bodies", "a password list", "a bad name beside it"],
)
def test_a_refused_login_never_repeats_the_password(
    app_client: Client, content: str, kind: str
) -> None:
    answer = app_client().post("/api/session", content=content, headers={"content-type": kind})
    assert answer.status_code == 422
    assert SECRET not in answer.text


def test_the_server_refuses_websocket_frames_over_its_limit_from_the_header(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import uvicorn

    from thermolab.cli import http_server

    given: dict[str, Any] = {}
    monkeypatch.setattr(uvicorn, "run", lambda app, **options: given.update(options))
    http_server.run_server(object(), "127.0.0.1", 8000)
    assert given["ws_max_size"] == http_server.WS_MAX_SIZE == 2**20
