"""Property-based fuzzing of the HTTP API from its OpenAPI: no input gives a 500.

Every operation of ``/openapi.json`` is called with generated path values,
query strings and JSON bodies (well-formed ones drawn near the schema, and
arbitrary JSON), as a student and as a teacher; every answer must be below 500
and, when it is a 4xx, JSON with a ``detail`` sentence.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from thermolab.lab.config import RigConfig
from thermolab.lab.http.app import create_app
from thermolab.lab.service import Lab
from thermolab.rigs import Rig, TwinRig, VirtualClock

from .conftest import PASSWORD, LabFactory


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


@pytest.fixture
def fuzz_client(make_lab: LabFactory) -> Iterator[tuple[TestClient, dict[str, dict[str, str]]]]:
    def opener(rig: RigConfig) -> Rig:
        return TwinRig("paper", clock=VirtualClock())

    lab: Lab = make_lab(opener=opener)
    headers = {}
    for name, role in (("ana", "student"), ("tina", "teacher")):
        token, _ = lab.sessions.create(lab.users.add(name, PASSWORD, role))
        headers[name] = {"cookie": f"thermolab_session={token}"}
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        yield client, headers


json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**12), 10**12)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=20),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=10,
)
field_values = (
    st.sampled_from([0, 1, -1, 0.1, 5.0, 1e9, "step:0:10@10", "square:4:6:0.1", "", "x" * 70])
    | json_values
)
names = st.sampled_from(
    [
        "dt",
        "samples",
        "signal",
        "setpoint",
        "methods",
        "window",
        "gamma",
        "u",
        "seconds",
        "username",
        "password",
        "role",
        "inService",
        "currentPassword",
    ]
)
path_values = st.sampled_from(
    ["twin", "other", "ana", "tina", "1", "0", "-1", "999999", "%20", "a" * 70]
)


def operations(spec: dict[str, Any]) -> list[tuple[str, str]]:
    return [
        (method.upper(), path)
        for path, ops in spec["paths"].items()
        for method in ops
        if not path.endswith("/session")  # logging out mid-fuzz would only test 401s
    ]


@pytest.mark.slow
def test_no_request_makes_the_server_fail(
    fuzz_client: tuple[TestClient, dict[str, dict[str, str]]],
) -> None:
    client, headers = fuzz_client
    ops = operations(client.get("/openapi.json").json())
    assert len(ops) >= 20

    @settings(
        max_examples=200,
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )
    @given(
        op=st.sampled_from(ops),
        who=st.sampled_from(["ana", "tina"]),
        path_value=path_values,
        body=st.one_of(st.dictionaries(names, field_values, max_size=5), json_values),
        query=st.dictionaries(
            st.sampled_from(["rig", "since", "x"]), st.text(max_size=5), max_size=2
        ),
    )
    def call(
        op: tuple[str, str], who: str, path_value: str, body: Any, query: dict[str, str]
    ) -> None:
        method, template = op
        path = re.sub(r"\{[^}]+\}", path_value, template)
        kwargs: dict[str, Any] = {"headers": headers[who], "params": query}
        if method in ("POST", "PUT", "PATCH"):
            kwargs["json"] = body
        response = client.request(method, path, **kwargs)
        assert response.status_code < 500, (method, path, body, response.text)
        if 400 <= response.status_code < 500:
            if response.headers.get("content-type", "").startswith("text/html"):
                # The LMS-facing LTI routes answer a browser with a page naming the code.
                assert path.startswith("/api/lti/"), (method, path, response.text)
                assert "lti_" in response.text, (method, path, response.text)
                return
            detail = response.json()["detail"]
            assert isinstance(detail, str)
            assert detail

    call()
