"""The HTTP API: authentication, cookies, throttling, roles, validation, errors, OpenAPI."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from thermolab.lab.clock import ManualClock
from thermolab.lab.http.app import create_app
from thermolab.lab.runs import MAX_DT, MAX_SAMPLES, MIN_DT, OFFSET_MODES
from thermolab.lab.service import Lab

from .conftest import PASSWORD, LabFactory
from .test_runs import twin_lab

Client = Callable[..., TestClient]


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    """The HTTP layer is the same on both backends (the access model is tested on both)."""
    return sqlite_url


@pytest.fixture
def people(lab: Lab) -> None:
    for name in ("ana", "ben", "cai"):
        lab.users.add(name, PASSWORD, "student")
    lab.users.add("tina", PASSWORD, "teacher", admin=True)


#: The LTI routes an LMS sends a browser to (no lab login; see docs/lti.md).
LMS_FACING = {"/api/lti/login", "/api/lti/launch", "/api/lti/continue"}


def _concrete(path: str) -> str:
    return re.sub(r"\{rig_id\}", "twin", re.sub(r"\{username\}", "ana", path))


@pytest.mark.usefixtures("people")
def test_every_route_but_login_version_privacy_and_enrol_needs_a_session(
    lab: Lab, app_client: Client
) -> None:
    client = app_client()
    spec = client.get("/openapi.json").json()
    checked = 0
    for path, operations in spec["paths"].items():
        for method in operations:
            response = client.request(method.upper(), _concrete(path), json={})
            if (method, path) == ("post", "/api/session"):
                assert response.status_code == 422  # no credentials in {}
                continue
            if (method, path) == ("get", "/api/version"):
                assert response.status_code == 200  # what a client reads before logging in
                continue
            if (method, path) == ("get", "/api/privacy"):
                assert response.status_code == 200  # what the lab keeps: the public privacy page
                continue
            if (method, path) == ("post", "/api/enrol"):
                assert response.status_code == 422  # self-enrolment: a code, not a login
                continue
            if (method, path) == ("get", "/api/calendar/{token}"):
                # A calendar app reads a feed with no login: its secret address is the key,
                # and an address that is no feed's is not found (this one is too short).
                assert response.status_code == 422, response.text
                unknown = client.get("/api/calendar/" + "x" * 43 + ".ics")
                assert unknown.status_code == 404, unknown.text
                continue
            if path == "/api/lti/jwks":
                assert response.status_code == 200  # the tool's public keys, for any LMS
                continue
            if path in LMS_FACING:
                # An LMS's browser arrives without a login: a signed token or a one-use
                # state authenticates it; without them it is refused (400, or 422 for no ticket).
                assert response.status_code in (400, 422), (method, path)
                continue
            assert response.status_code == 401, (method, path)
            assert response.json()["detail"].startswith("not logged in")
            checked += 1
    assert checked >= 15
    for method, path in [("GET", "/api/nothing/here"), ("PATCH", "/api/rigs/twin")]:
        response = client.request(method, path)
        assert (response.status_code, response.json()["detail"]) == (401, "not logged in")


@pytest.mark.usefixtures("people")
def test_login_sets_a_strict_httponly_cookie_and_logout_ends_it(app_client: Client) -> None:
    client = app_client()
    response = client.post("/api/session", json={"username": "ana", "password": PASSWORD})
    assert response.status_code == 200
    assert response.json()["username"] == "ana"
    cookie = response.headers["set-cookie"]
    assert cookie.startswith("thermolab_session=")
    attributes = {part.strip().lower() for part in cookie.split(";")[1:]}
    assert {"httponly", "samesite=strict", "path=/"} <= attributes
    assert "secure" not in attributes
    assert client.get("/api/session").json()["role"] == "student"
    assert client.delete("/api/session").status_code == 204
    assert client.get("/api/session").status_code == 401


@pytest.mark.usefixtures("people")
def test_the_cookie_is_secure_over_https(app_client: Client) -> None:
    client = app_client(base_url="https://lab.example")
    response = client.post("/api/session", json={"username": "ana", "password": PASSWORD})
    assert "secure" in response.headers["set-cookie"].lower()


@pytest.mark.usefixtures("people")
def test_wrong_passwords_are_refused_and_throttled(
    app_client: Client, clock: ManualClock, caplog: pytest.LogCaptureFixture
) -> None:
    client = app_client()
    with caplog.at_level("WARNING", logger="thermolab.lab.http.routers.session"):
        for _ in range(6):
            response = client.post("/api/session", json={"username": "ana", "password": "guess!!!"})
            assert (response.status_code, response.json()) == (
                401,
                {
                    "detail": "wrong user name or password",
                    "code": "not_authenticated",
                    "message": "You are not logged in, or the user name or password is wrong.",
                },
            )
    # ASVS V7.2.1: each failure is logged with the name and the address, never the password.
    failures = [r.getMessage() for r in caplog.records if "login failed" in r.getMessage()]
    assert failures == ["login failed: user 'ana' from testclient"] * 6
    assert "guess" not in caplog.text
    response = client.post("/api/session", json={"username": "ana", "password": PASSWORD})
    assert response.status_code == 429
    assert response.headers["retry-after"] == "1"
    assert "too many failed logins for 'ana' from testclient" in response.json()["detail"]
    # Another account from the same address is not delayed by ana's failures.
    assert (
        client.post("/api/session", json={"username": "ben", "password": PASSWORD}).status_code
        == 200
    )
    # The delay is short and bounded: the right password gets in after it (no lock-out).
    clock.advance(1)
    assert (
        client.post("/api/session", json={"username": "ana", "password": PASSWORD}).status_code
        == 200
    )


@pytest.mark.usefixtures("people")
def test_login_attempts_are_throttled_per_address(app_client: Client) -> None:
    client = app_client()
    for i in range(30):
        client.post("/api/session", json={"username": f"user{i}", "password": "whatever"})
    response = client.post("/api/session", json={"username": "ana", "password": PASSWORD})
    assert response.status_code == 429
    assert "from testclient" in response.json()["detail"]


@pytest.mark.usefixtures("people")
def test_students_cannot_act_on_others_or_manage_the_lab(app_client: Client) -> None:
    ana, ben = app_client("ana"), app_client("ben")
    assert ana.post("/api/rigs/twin/control").json()["access"]["role"] == "controller"
    ben.post("/api/rigs/twin/control")
    # ben releasing only leaves his own queue place; ana keeps control.
    assert ben.delete("/api/rigs/twin/control").json()["access"]["controller"] == "ana"
    forbidden = [
        ("POST", "/api/rigs/twin/control/kick", {}),
        ("POST", "/api/rigs/twin/control/extend", {"seconds": 60}),
        ("PUT", "/api/rigs/twin/service", {"inService": False}),
        ("GET", "/api/users", None),
        ("POST", "/api/users", {"username": "eve", "password": PASSWORD, "role": "teacher"}),
        ("DELETE", "/api/users/ana", None),
        ("PUT", "/api/users/ana/password", {"password": "taken over by ben"}),
        ("PUT", "/api/rigs/twin/input", {"u": 1.0}),
    ]
    for method, path, body in forbidden:
        response = ben.request(method, path, json=body)
        assert response.status_code == 403, (method, path)
        assert response.json()["detail"]
    assert ana.get("/api/session").status_code == 200


@pytest.mark.usefixtures("people")
def test_changing_your_own_password_needs_the_current_one(app_client: Client) -> None:
    ana = app_client("ana")
    response = ana.put("/api/users/ana/password", json={"password": "a new passphrase"})
    assert (response.status_code, response.json()["detail"]) == (
        422,
        "currentPassword (your own current password) is required to change a password",
    )
    response = ana.put(
        "/api/users/ana/password",
        json={"password": "a new passphrase", "currentPassword": "wrong password"},
    )
    assert response.status_code == 403
    response = ana.put(
        "/api/users/ana/password",
        json={"password": "a new passphrase", "currentPassword": PASSWORD},
    )
    assert response.status_code == 204
    assert ana.get("/api/session").status_code == 200  # this login stays


@pytest.mark.usefixtures("people")
def test_teachers_manage_accounts_and_see_queues_and_watchers(app_client: Client) -> None:
    tina, ana, ben = app_client("tina"), app_client("ana"), app_client("ben")
    ana.post("/api/rigs/twin/control")
    ben.post("/api/rigs/twin/control")
    rig = tina.get("/api/rigs/twin").json()
    assert [q["username"] for q in rig["queue"]] == ["ben"]
    assert {w["username"] for w in rig["watcherList"]} == {"ana", "ben", "tina"}
    assert rig["access"]["watchers"] == 3
    student_view = ana.get("/api/rigs/twin").json()
    assert (student_view["queue"], student_view["watcherList"]) == (None, None)
    assert (
        tina.post("/api/rigs/twin/control/extend", json={"seconds": 60}).json()["access"][
            "controller"
        ]
        == "ana"
    )
    assert ana.get("/api/rigs/twin").json()["access"]["timeLeft"] == 360.0
    kicked = tina.post("/api/rigs/twin/control/kick", json={}).json()
    assert kicked["access"]["controller"] == "ben"
    history = tina.get("/api/rigs/twin/control-sessions").json()
    assert [(h["username"], h["endReason"], h["endedBy"]) for h in history] == [
        ("ben", None, None),
        ("ana", "kicked", "tina"),
    ]
    assert [h["username"] for h in ana.get("/api/rigs/twin/control-sessions").json()] == ["ana"]
    created = tina.post(
        "/api/users", json={"username": "dee", "password": PASSWORD, "role": "student"}
    )
    assert (created.status_code, created.json()["username"]) == (201, "dee")
    duplicate = tina.post(
        "/api/users", json={"username": "dee", "password": PASSWORD, "role": "student"}
    )
    assert (duplicate.status_code, duplicate.json()["detail"]) == (
        409,
        "user 'dee' already exists",
    )
    # Re-authentication: a teacher changing someone else's password gives her own.
    for body, status in [
        ({"password": "another passphrase"}, 422),
        ({"password": "another passphrase", "currentPassword": "not tina's one"}, 403),
        ({"password": "another passphrase", "currentPassword": PASSWORD}, 204),
    ]:
        assert tina.put("/api/users/dee/password", json=body).status_code == status
    assert tina.delete("/api/users/dee").status_code == 204
    assert tina.delete("/api/users/dee").status_code == 404
    assert tina.delete("/api/users/tina").status_code == 403
    assert [u["username"] for u in tina.get("/api/users").json()] == ["ana", "ben", "cai", "tina"]


@pytest.mark.usefixtures("people")
def test_inputs_are_validated_with_clear_messages(app_client: Client) -> None:
    ana = app_client("ana")
    ana.post("/api/rigs/twin/control")
    ok = ana.put("/api/rigs/twin/input", json={"u": 2.5})
    assert ok.status_code == 200
    assert (ok.json()["u"], ok.json()["applied"]) == (2.5, None)
    cases = [
        ({"u": 11}, "u = 11 V is outside the input range of rig 'twin': [-10, 10] V"),
        ({"u": -10.5}, "u = -10.5 V is outside the input range"),
        ({"u": "5"}, "u: Input should be a valid number (got '5')"),
        ({"u": None}, "u: Input should be a valid number"),
        ({"u": True}, "u: Input should be a valid number"),
        ({"u": 1, "v": 2}, "v: unknown field"),
        ({}, "u: Field required"),
    ]
    for body, message in cases:
        response = ana.put("/api/rigs/twin/input", json=body)
        assert response.status_code == 422, body
        assert message in response.json()["detail"], response.json()
    for raw, message in [
        (b'{"u": NaN}', "u: Input should be a finite number"),
        (b'{"u": Infinity}', "u: Input should be a finite number"),
        (b'{"u": ', "the request body is not valid JSON"),
        (b"", "the request body is missing"),
        (b"[1, 2]", "Input should be a valid dictionary"),
    ]:
        response = ana.put(
            "/api/rigs/twin/input", content=raw, headers={"content-type": "application/json"}
        )
        assert response.status_code == 422, raw
        assert message in response.json()["detail"], response.json()
    # None of that harmed the session or the control.
    assert ana.get("/api/rigs/twin").json()["access"]["role"] == "controller"
    assert ana.get("/api/rigs/twin").json()["input"]["last"] == 2.5


@pytest.mark.usefixtures("people")
def test_oversized_bodies_are_refused_without_harm(app_client: Client) -> None:
    ana = app_client("ana")
    big = b'{"u": 1, "pad": "' + b"x" * 70_000 + b'"}'
    response = ana.put(
        "/api/rigs/twin/input", content=big, headers={"content-type": "application/json"}
    )
    assert response.status_code == 413
    assert "request body too large" in response.json()["detail"]
    # Sent in chunks without a declared length: refused while reading.
    response = ana.put(
        "/api/rigs/twin/input",
        content=iter([b'{"u": "', b"x" * 40_000, b"x" * 40_000, b'"}']),
        headers={"content-type": "application/json"},
    )
    assert response.status_code == 413
    assert ana.get("/api/session").status_code == 200


@pytest.mark.usefixtures("people")
def test_unknown_things_are_json_errors(app_client: Client) -> None:
    ana = app_client("ana")
    response = ana.get("/api/rigs/nope")
    assert (response.status_code, response.json()["detail"]) == (
        404,
        "no rig called 'nope'; the lab has: twin, other",
    )
    # START on a rig that does not exist (it was a KeyError and a 500).
    response = ana.post("/api/rigs/nope/runs", json={"dt": 1, "samples": 10, "setpoint": 0})
    assert (response.status_code, response.json()["detail"]) == (
        404,
        "no rig called 'nope'; the lab has: twin, other",
    )
    response = ana.get("/api/nothing")
    assert (response.status_code, response.json()["detail"]) == (
        404,
        "nothing at GET /api/nothing; see /openapi.json",
    )
    response = ana.get("/api/rigs/twin/input")
    assert response.status_code == 405
    assert response.json()["detail"] == "GET is not allowed on /api/rigs/twin/input; use PUT"
    assert ana.post("/api/rigs/twin/control/kick", json={}).status_code == 403


@pytest.mark.usefixtures("people")
def test_the_rig_list_and_heartbeat(app_client: Client) -> None:
    ana = app_client("ana")
    rigs = ana.get("/api/rigs").json()
    assert [(r["id"], r["state"], r["input"]["unit"]) for r in rigs] == [
        ("twin", "off", "V"),
        ("other", "off", "%"),
    ]
    assert rigs[0]["limits"]["controlTimeLimit"] == 300.0
    ana.post("/api/rigs/other/control")
    beat = ana.post("/api/rigs/other/heartbeat").json()
    assert (beat["access"]["role"], beat["state"]) == ("controller", "in_use")
    assert ana.put("/api/rigs/other/input", json={"u": 100}).status_code == 200
    assert ana.put("/api/rigs/other/input", json={"u": -1}).status_code == 422


def test_openapi_documents_the_api(lab: Lab) -> None:
    spec = create_app(lab.config, lab=lab).openapi()
    paths = spec["paths"]
    for path in [
        "/api/session",
        "/api/rigs",
        "/api/rigs/{rig_id}",
        "/api/rigs/{rig_id}/control",
        "/api/rigs/{rig_id}/control/extend",
        "/api/rigs/{rig_id}/control/kick",
        "/api/rigs/{rig_id}/heartbeat",
        "/api/rigs/{rig_id}/input",
        "/api/rigs/{rig_id}/service",
        "/api/users",
        "/api/users/{username}/password",
    ]:
        assert path in paths, path
    assert set(paths["/api/rigs/{rig_id}/input"]["put"]["responses"]) >= {
        "200",
        "401",
        "403",
        "404",
        "422",
    }
    assert "429" in paths["/api/session"]["post"]["responses"]
    assert spec["components"]["securitySchemes"]["APIKeyCookie"]["name"] == "thermolab_session"
    access = spec["components"]["schemas"]["AccessOut"]["properties"]
    assert {"queueSize", "queuePosition", "estimatedTimeUntilControl", "timeLeft"} <= set(access)


def test_openapi_publishes_the_bounds_the_service_applies(lab: Lab) -> None:
    """One source of truth: the browser reads these ranges from /openapi.json."""
    spec = create_app(lab.config, lab=lab).openapi()
    run_in = spec["components"]["schemas"]["RunIn"]["properties"]
    assert (run_in["dt"]["minimum"], run_in["dt"]["maximum"]) == (MIN_DT, MAX_DT)
    assert run_in["samples"]["maximum"] == MAX_SAMPLES
    gamma = next(b for b in run_in["gamma"]["anyOf"] if b.get("type") == "number")
    assert (gamma["exclusiveMinimum"], gamma["exclusiveMaximum"]) == (0, 1)
    w0 = next(b for b in run_in["w0"]["anyOf"] if b.get("type") == "array")
    assert (w0["minItems"], w0["maxItems"], w0["items"]["type"]) == (2, 3, "number")
    modes = next(b for b in run_in["offset"]["anyOf"] if "enum" in b)
    assert modes["enum"] == list(OFFSET_MODES)
    assert run_in["offset"]["default"] == "auto"
    run_out = spec["components"]["schemas"]["RunOut"]["properties"]
    assert "operatingPoint" in run_out
    runs = spec["paths"]["/api/runs"]["get"]
    assert "user" in [p["name"] for p in runs["parameters"]]
    assert {"403", "404"} <= set(runs["responses"])


@pytest.mark.usefixtures("people")
def test_listing_the_rigs_is_not_watching_them(app_client: Client, lab: Lab) -> None:
    ana, ben, tina = app_client("ana"), app_client("ben"), app_client("tina")
    for client in (ana, ben, tina, ana):
        rigs = client.get("/api/rigs").json()
        assert [r["access"]["watchers"] for r in rigs] == [0, 0]
    assert [r["watcherList"] for r in tina.get("/api/rigs").json()] == [[], []]
    # Explicit heartbeats and requests for one rig count (the rig page polls it
    # while its live socket is down); so does a live connection (tests/lab/test_live.py).
    ben.post("/api/rigs/twin/heartbeat")
    ana.post("/api/rigs/other/control")
    assert [r["access"]["watchers"] for r in tina.get("/api/rigs").json()] == [1, 1]
    # A teacher acting on a rig from the overview is not watching it either.
    tina.post("/api/rigs/other/control/extend", json={"seconds": 30})
    rigs = tina.get("/api/rigs").json()
    assert [[w["username"] for w in r["watcherList"]] for r in rigs] == [["ben"], ["ana"]]
    tina.get("/api/rigs/twin")
    assert [w.username for w in lab.presence.watchers("twin")] == ["ben", "tina"]


@pytest.mark.usefixtures("people")
def test_everyone_sees_the_controllers_time_left(app_client: Client, clock: ManualClock) -> None:
    ana, ben, cai = app_client("ana"), app_client("ben"), app_client("cai")
    tina = app_client("tina")
    assert ben.get("/api/rigs/twin").json()["access"]["timeLeft"] is None  # nobody controls
    ana.post("/api/rigs/twin/control")
    ben.post("/api/rigs/twin/control")
    clock.advance(10)
    for client, role in ((ana, "controller"), (ben, "queued"), (cai, "watcher")):
        access = client.get("/api/rigs/twin").json()["access"]
        assert (access["role"], access["timeLeft"]) == (role, 290.0)
        assert (access["idleTimeLeft"] is not None) == (role == "controller")
    tina.post("/api/rigs/twin/control/extend", json={"seconds": 60})
    lobby = cai.get("/api/rigs").json()
    assert [r["access"]["timeLeft"] for r in lobby] == [350.0, None]


def test_the_browser_interface_is_served_when_given(lab: Lab, tmp_path: Path) -> None:
    (tmp_path / "index.html").write_text("<h1>ThermoLab</h1>")
    with TestClient(create_app(lab.config, tmp_path, lab=lab, sweep_interval=None)) as client:
        assert client.get("/").text == "<h1>ThermoLab</h1>"
        assert client.get("/api/rigs").status_code == 401
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        response = client.get("/")
        assert (response.status_code, response.json()["detail"]) == (
            404,
            "nothing at GET /; see /openapi.json",
        )


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ({"dt": 0, "samples": 10}, "dt must be between 0.01 and 3600 seconds, got 0.0"),
        ({"dt": 3601, "samples": 10}, "dt must be between 0.01 and 3600 seconds, got 3601.0"),
        ({"dt": 1, "samples": 200_001}, "samples: Input should be less than or equal to 200000"),
        ({"dt": 1, "samples": 0}, "samples: Input should be greater than or equal to 1"),
        ({"dt": 1, "samples": 2.5}, "samples: Input should be a valid integer"),
        ({"dt": 1, "samples": 10, "signal": "ramp:0:1"}, "invalid signal 'ramp:0:1'"),
        ({"dt": 1, "samples": 10, "signal": "step:0:11@1"}, "outside the input range"),
        ({"dt": 1, "samples": 10, "setpoint": 12}, "setpoint 12.0 is outside"),
        (
            {"dt": 1, "samples": 10, "signal": "const:1", "setpoint": 1},
            "give either a signal or a setpoint",
        ),
        (
            {"dt": 1, "samples": 10, "methods": ["rls"]},
            "methods.0: Input should be one of srm, lsm, blockls, malsm, wlsm",
        ),
        ({"dt": 1, "samples": 10, "methods": ["srm"], "gamma": 0.9}, "gamma is a setting of wlsm"),
        ({"dt": 1, "samples": 10, "colour": "red"}, "colour: unknown field"),
        ({"dt": 1, "samples": 10, "methods": []}, "methods: List should have at least 1 item"),
        ({"dt": 1, "samples": 10, "methods": ["wlsm"], "gamma": 1}, "gamma: Input should be less"),
        ({"dt": 1, "samples": 10, "methods": ["wlsm"], "w0": [0.9]}, "w0: List should have at"),
        (
            {"dt": 1, "samples": 10, "methods": ["wlsm"], "w0": [0.9, 0.01, 0, 0]},
            "w0: List should have at most 3 items",
        ),
        (
            {"dt": 1, "samples": 10, "methods": ["wlsm"], "w0": [0.9, "x"]},
            "w0.1: Input should be a valid number",
        ),
        (
            {"dt": 1, "samples": 10, "methods": ["wlsm"], "w0": [0.9, 0.01, 0]},
            "w0 must have 2 entries [a0, b0] (3, with the constant term c0, only with offset",
        ),
        ({"dt": 1, "samples": 10, "methods": ["lsm"], "w0": [0.9, 0.01]}, "w0 is a setting of"),
        (
            {"dt": 1, "samples": 10, "offset": "warm"},
            "offset: Input should be 'auto', 'initial', 'fit', 'none' or a finite number",
        ),
        ({"dt": 1, "samples": 10, "offset": True}, "offset: Input should be 'auto'"),
        ({"dt": 1, "samples": 10, "methods": ["srm"], "offset": "fit"}, "offset is a setting of"),
    ],
)
def test_bad_run_requests_are_refused_with_the_reason(
    make_lab: LabFactory, body: dict[str, object], message: str
) -> None:
    lab = twin_lab(make_lab)  # a live twin: runs need a device
    lab.users.add("ana", PASSWORD, "student")
    with TestClient(create_app(lab.config, lab=lab, sweep_interval=None)) as client:
        client.post("/api/session", json={"username": "ana", "password": PASSWORD})
        client.post("/api/rigs/twin/control")
        response = client.post("/api/rigs/twin/runs", json=body)
    assert response.status_code == 422, response.text
    assert message in response.json()["detail"]
