"""Browser-side protections (issue #13 item 5) and what answers may show (item 4)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from thermolab.errors import ConfigError
from thermolab.lab.config import load_config
from thermolab.lab.http.app import create_app
from thermolab.lab.http.deps import COOKIE_NAME
from thermolab.lab.service import Lab

from .conftest import PASSWORD

# On SQLite alone: request guards and answer shapes, before and after any store
# (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only

FOREIGN = "https://evil.example"


def _client(lab: Lab, **access: Any) -> TestClient:
    config = replace(lab.config, access=replace(lab.config.access, **access))
    return TestClient(create_app(config, lab=lab, sweep_interval=None))


def _logged_in(lab: Lab, name: str = "ana") -> dict[str, str]:
    if name not in {u.username for u in lab.users.list()}:
        lab.users.add(name, PASSWORD, "student")
    token, _ = lab.sessions.create(lab.users.get(name))
    return {"cookie": f"{COOKIE_NAME}={token}"}


@pytest.mark.parametrize(
    ("method", "path", "json"),
    [
        ("POST", "/api/rigs/twin/control", None),  # body-less
        ("DELETE", "/api/rigs/twin/control", None),
        ("DELETE", "/api/session", None),
        ("PUT", "/api/rigs/twin/input", {"u": 1.0}),
        ("POST", "/api/session", {"username": "ana", "password": PASSWORD}),
    ],
)
@pytest.mark.parametrize(
    "headers",
    [
        {"origin": FOREIGN},
        {"origin": "null"},
        {"origin": "http://testserver:8080"},  # another port is another origin
        {"sec-fetch-site": "cross-site", "origin": "http://testserver"},
        {"sec-fetch-site": "same-site"},
    ],
)
def test_cross_origin_state_changes_are_refused(
    lab: Lab, method: str, path: str, json: Any, headers: dict[str, str]
) -> None:
    with _client(lab) as client:
        response = client.request(method, path, json=json, headers={**_logged_in(lab), **headers})
    assert response.status_code == 403
    assert response.json()["code"] == "cross_origin"


@pytest.mark.parametrize(
    "headers",
    [
        {},  # not from a browser page: no cookie to abuse
        {"origin": "http://testserver"},
        {"origin": "http://TESTSERVER:80"},
        {"sec-fetch-site": "same-origin", "origin": "http://testserver"},
        {"sec-fetch-site": "none"},
    ],
)
def test_same_origin_state_changes_pass(lab: Lab, headers: dict[str, str]) -> None:
    with _client(lab) as client:
        response = client.post("/api/rigs/twin/control", headers={**_logged_in(lab), **headers})
    assert response.status_code == 200, response.text


def test_reading_from_anywhere_is_not_a_state_change(lab: Lab) -> None:
    with _client(lab) as client:
        response = client.get("/api/rigs", headers={**_logged_in(lab), "origin": FOREIGN})
    assert response.status_code == 200


def test_the_live_socket_refuses_a_foreign_origin(lab: Lab) -> None:
    headers = _logged_in(lab)
    with _client(lab) as client:
        with (
            pytest.raises(WebSocketDisconnect) as refused,
            client.websocket_connect("/api/rigs/twin/live", headers={**headers, "origin": FOREIGN}),
        ):
            pass
        assert refused.value.code == 1008
        with client.websocket_connect(
            "/api/rigs/twin/live", headers={**headers, "origin": "http://testserver"}
        ) as ws:
            assert ws.receive_json()["type"] == "hello"


def test_security_headers(lab: Lab) -> None:
    with _client(lab) as client:
        api = client.get("/api/rigs", headers=_logged_in(lab))
        schema = client.get("/openapi.json")
        refused = client.get("/api/rigs")
    for response in (api, schema, refused):
        csp = response.headers["content-security-policy"]
        assert "script-src 'self'" in csp
        assert "unsafe-inline" not in csp
        assert "frame-ancestors 'self'" in csp
        assert response.headers["x-content-type-options"] == "nosniff"
        assert response.headers["referrer-policy"] == "same-origin"
        assert response.headers["x-frame-options"] == "SAMEORIGIN"
        assert response.headers["cache-control"] == "no-store"


def test_frame_ancestors_are_configurable_for_an_lms(lab: Lab) -> None:
    lms = ("'self'", "https://moodle.example.edu")
    with _client(lab, frame_ancestors=lms) as client:
        response = client.get("/openapi.json")
    assert (
        "frame-ancestors 'self' https://moodle.example.edu"
        in response.headers["content-security-policy"]
    )
    assert "x-frame-options" not in response.headers  # it cannot name the LMS


def test_api_docs_are_served_from_the_package(lab: Lab) -> None:
    with _client(lab) as client:
        for page in ("/docs", "/redoc"):
            html = client.get(page)
            assert html.status_code == 200
            assert "cdn" not in html.text.lower()
            assert "https://" not in html.text
            assert "<script>" not in html.text  # no inline script: the CSP forbids it
            csp = html.headers["content-security-policy"]
            assert "script-src 'self';" in csp
        for asset in (
            "/docs/assets/swagger-ui-bundle.js",
            "/docs/assets/swagger-ui.css",
            "/docs/assets/redoc.standalone.js",
            "/docs/start.js",
        ):
            assert client.get(asset).status_code == 200, asset
        assert "/openapi.json" in client.get("/docs/start.js").text


def test_proxy_headers_are_trusted_only_from_configured_addresses(lab: Lab) -> None:
    lab.users.add("ana", PASSWORD, "student")
    forwarded = {"x-forwarded-for": "203.0.113.9"}
    # Default: trust none, so a client cannot pick the address the throttle counts.
    with _client(lab) as client:
        for _ in range(31):
            response = client.post(
                "/api/session", json={"username": "ana", "password": "guess!!!"}, headers=forwarded
            )
        assert response.status_code == 429
        assert "from testclient" in response.json()["detail"]
    with _client(lab, trusted_proxies=("testclient",)) as client:
        response = client.post(
            "/api/session", json={"username": "ana", "password": "guess!!!"}, headers=forwarded
        )
        assert response.status_code == 401  # counted for 203.0.113.9, not for the proxy


def test_no_answer_echoes_a_submitted_password(lab: Lab) -> None:
    secret = "hunter2-hunter2" * 70  # too long: 422
    with _client(lab) as client:
        bodies = [
            client.post("/api/session", json={"username": "ana", "password": secret}),
            client.post("/api/session", json={"username": "ana", "password": 12345678}),
            client.put(
                "/api/users/ana/password",
                json={"password": "zq9zq9", "currentPassword": secret},
                headers=_logged_in(lab),
            ),
        ]
    for response in bodies:
        assert response.status_code == 422
        assert "hunter2" not in response.text
        assert "12345678" not in response.text
        assert "zq9zq9" not in response.text


def test_the_new_access_keys_are_read_from_toml(tmp_path: Path) -> None:
    rig = '[[rigs]]\nid = "twin"\nspec = "sim"\n'
    config_file = tmp_path / "lab.toml"
    config_file.write_text(
        '[access]\ntrusted_proxies = ["10.0.0.2"]\n'
        'frame_ancestors = ["\'self\'", "https://moodle.example.edu"]\n' + rig,
        encoding="utf-8",
    )
    access = load_config(config_file, tmp_path).access
    assert access.trusted_proxies == ("10.0.0.2",)
    assert access.frame_ancestors == ("'self'", "https://moodle.example.edu")
    config_file.write_text(
        '[access]\nframe_ancestors = ["a; script-src *"]\n' + rig, encoding="utf-8"
    )
    with pytest.raises(
        ConfigError,
        match=r"access\.frame_ancestors\[0\]: expected one word without spaces, ';' or ','",
    ):
        load_config(config_file, tmp_path)


def test_re_authentication_is_throttled_like_a_login(lab: Lab) -> None:
    headers = _logged_in(lab, "ana")
    with _client(lab) as client:
        codes = [
            client.put(
                "/api/users/ana/password",
                json={"password": "a new passphrase", "currentPassword": "a wrong guess"},
                headers=headers,
            ).status_code
            for _ in range(7)
        ]
    assert codes == [403] * 5 + [403, 429]
