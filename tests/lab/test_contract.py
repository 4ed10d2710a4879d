"""The API's contract is exact: what ``/openapi.json`` and docs/live-protocol.md say is
what the server does.

Every path and query parameter is bounded in the schema; every 422 (path, query,
body, a body that is not UTF-8, the lab's own refusals) is the one published
shape; a wrong method gets 405 with ``Allow`` naming the methods the path really
has (with and without the browser interface mounted at ``/``); the live
socket's handshake refuses a malformed ``since`` with the documented close code.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from thermolab.lab.http.app import create_app
from thermolab.lab.http.deps import MAX_ROW_ID
from thermolab.lab.live.fanout import CLOSE_BAD_REQUEST, CLOSE_UNAUTHORIZED, MAX_SEQ
from thermolab.lab.service import Lab
from thermolab.web import STATIC_DIR

from .conftest import PASSWORD

METHODS = ("GET", "POST", "PUT", "DELETE", "PATCH")


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


@pytest.fixture
def spec(lab: Lab) -> dict[str, Any]:
    return create_app(lab.config, lab=lab, sweep_interval=None).openapi()


def _parameters(spec: dict[str, Any]) -> Iterator[tuple[str, str, dict[str, Any]]]:
    for path, operations in spec["paths"].items():
        for method, operation in operations.items():
            for parameter in operation.get("parameters", []):
                yield f"{method.upper()} {path}", parameter["in"], parameter


def _alternatives(schema: dict[str, Any]) -> list[dict[str, Any]]:
    """The non-null schemas of a parameter (``str | None`` is an ``anyOf`` with null)."""
    options = schema.get("anyOf", [schema])
    return [option for option in options if option.get("type") != "null"]


def test_every_path_and_query_parameter_is_bounded(spec: dict[str, Any]) -> None:
    checked = 0
    for operation, place, parameter in _parameters(spec):
        if place not in ("path", "query"):
            continue
        where = f"{operation} {place} {parameter['name']}"
        for schema in _alternatives(parameter["schema"]):
            checked += 1
            if "enum" in schema:
                continue
            kind = schema.get("type")
            if kind == "integer":
                # The databases' INTEGER (signed 32 bits): no larger id reaches the driver.
                assert schema.get("minimum", -(2**32)) >= -(2**31), where
                assert schema.get("maximum", 2**32) <= MAX_ROW_ID, where
            elif kind == "string":
                assert schema.get("minLength", 0) >= 1, where
                assert schema.get("maxLength", 10**9) <= 64, where
                assert "pattern" in schema, where
            elif kind == "number":
                low = schema.get("minimum", schema.get("exclusiveMinimum"))
                high = schema.get("maximum", schema.get("exclusiveMaximum"))
                assert low is not None, where
                assert high is not None, where
            else:
                pytest.fail(f"{where}: a {kind} parameter has no bounds in the schema")
    assert checked >= 15  # rig ids, run ids, user names, the listing's filters


def test_every_422_is_published_as_the_body_sent(spec: dict[str, Any]) -> None:
    schemas = spec["components"]["schemas"]
    assert "HTTPValidationError" not in schemas  # FastAPI's own, which we never send
    published = schemas["ValidationErrorOut"]
    assert set(published["required"]) == {"detail", "code", "errors"}
    for path, operations in spec["paths"].items():
        for method, operation in operations.items():
            takes_input = operation.get("parameters") or "requestBody" in operation
            invalid = operation["responses"].get("422")
            if not takes_input:
                continue
            assert invalid is not None, f"{method.upper()} {path} documents no 422"
            assert invalid["content"]["application/json"]["schema"] == {
                "$ref": "#/components/schemas/ValidationErrorOut"
            }, f"{method.upper()} {path}"


def _assert_published_422(response: Any, code: str) -> dict[str, Any]:
    assert response.status_code == 422, response.text
    body: dict[str, Any] = response.json()
    # "message" is the code's sentence in the reader's language (optional in the schema).
    assert set(body) == {"detail", "code", "message", "errors"}, body
    assert isinstance(body["detail"], str)
    assert body["detail"]
    assert body["code"] == code
    assert body["errors"]
    for problem in body["errors"]:
        assert set(problem) == {"loc", "type", "msg"}, problem
        assert all(isinstance(part, str) for part in problem["loc"])
        assert isinstance(problem["type"], str)
        assert isinstance(problem["msg"], str)
    return body


@pytest.mark.parametrize(
    ("request_line", "where"),
    [
        ("GET /api/runs/0", ["path", "run_id"]),
        (f"GET /api/runs/{MAX_ROW_ID + 1}/samples.csv", ["path", "run_id"]),
        ("GET /api/runs?rig=No%20such%20rig", ["query", "rig"]),
        ("GET /api/runs?user=%20", ["query", "user"]),
        ("POST /api/rigs/Twin!/control", ["path", "rig_id"]),
        ("DELETE /api/users/-x", ["path", "username"]),
    ],
)
def test_path_and_query_422s_match_the_published_schema(
    app_client: Callable[..., TestClient], lab: Lab, request_line: str, where: list[str]
) -> None:
    lab.users.add("tina", PASSWORD, "teacher")
    client = app_client("tina")
    method, url = request_line.split(" ")
    body = _assert_published_422(client.request(method, url), "invalid_request")
    assert [problem["loc"] for problem in body["errors"]] == [where]


def test_the_labs_own_422_matches_the_published_schema(
    app_client: Callable[..., TestClient], lab: Lab
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    client = app_client("ana")
    assert client.post("/api/rigs/twin/control").status_code == 200
    response = client.put("/api/rigs/twin/input", json={"u": 1e6})  # outside the rig's range
    body = _assert_published_422(response, "invalid_parameter")
    assert "range" in body["detail"]


@pytest.mark.parametrize("body", [b"\xff\xfe{}", b'{"username": "\xe9"}', b"\xc3"])
def test_a_body_that_is_not_utf8_is_a_documented_422(
    app_client: Callable[..., TestClient], lab: Lab, body: bytes
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    client = app_client("ana")
    assert client.post("/api/rigs/twin/control").status_code == 200
    headers = {"content-type": "application/json"}
    for method, url in (("POST", "/api/session"), ("PUT", "/api/rigs/twin/input")):
        response = client.request(method, url, content=body, headers=headers)
        problem = _assert_published_422(response, "invalid_request")["errors"][0]
        assert (problem["loc"][0], problem["type"]) == ("body", "json_invalid")


@pytest.mark.slow
@pytest.mark.parametrize("static", [False, True], ids=["api-only", "with-pages"])
def test_a_wrong_method_names_every_method_of_the_path(
    lab: Lab, spec: dict[str, Any], static: bool
) -> None:
    lab.users.add("tina", PASSWORD, "teacher")
    app = create_app(lab.config, STATIC_DIR if static else None, lab=lab, sweep_interval=None)
    with TestClient(app) as client:
        login = {"username": "tina", "password": PASSWORD}
        assert client.post("/api/session", json=login).status_code == 200
        checked = 0
        for template, operations in spec["paths"].items():
            path = template.replace("{rig_id}", "twin").replace("{run_id}", "1")
            path = path.replace("{username}", "nobody")
            allowed = sorted(method.upper() for method in operations)
            for method in METHODS:
                if method in allowed:
                    continue
                response = client.request(method, path)
                assert response.status_code == 405, (method, path, response.text)
                assert response.headers["allow"] == ", ".join(allowed), (method, path)
                assert response.json()["code"] == "method_not_allowed"
                checked += 1
        assert checked >= 50
        # An unknown path under /api is a 404 whatever the method, not the pages' 405.
        response = client.post("/api/nothing/here")
        assert (response.status_code, response.json()["code"]) == (404, "not_found")


@pytest.mark.parametrize("since", ["abc", "-1", "1.5", str(MAX_SEQ + 1), "1e3", ""])
def test_a_malformed_since_is_refused_as_documented(
    app_client: Callable[..., TestClient], lab: Lab, since: str
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    client = app_client("ana")
    url = f"/api/rigs/twin/live?since={since}"
    with client.websocket_connect(url) as ws, pytest.raises(WebSocketDisconnect) as refused:
        ws.receive_json()
    assert refused.value.code == CLOSE_BAD_REQUEST
    assert "since" in refused.value.reason
    # Without a login the answer is the same as for any other request: log in first.
    stranger = app_client()
    with stranger.websocket_connect(url) as ws, pytest.raises(WebSocketDisconnect) as refused:
        ws.receive_json()
    assert refused.value.code == CLOSE_UNAUTHORIZED


def test_a_valid_since_at_the_bounds_is_accepted(
    app_client: Callable[..., TestClient], lab: Lab
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    client = app_client("ana")
    for since in (0, MAX_SEQ):
        with client.websocket_connect(f"/api/rigs/twin/live?since={since}") as ws:
            assert ws.receive_json()["type"] == "hello"


def test_every_422_code_of_the_lab_is_published(spec: dict[str, Any]) -> None:
    # A lab refusal answered with 422 must carry a code the published schema allows
    # (schemathesis's response-conformance check fails otherwise).
    from thermolab.lab.http.errors import _FAULTS

    published = spec["components"]["schemas"]["ValidationErrorOut"]["properties"]["code"]["enum"]
    codes = {fault.code for fault in _FAULTS.values() if fault.status == 422}
    assert codes <= set(published), codes - set(published)
