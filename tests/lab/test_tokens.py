"""Personal API tokens: created once, hashed, scoped, refused at once when revoked (#11)."""

from __future__ import annotations

import pytest
from sqlalchemy import select

from thermolab.lab.accounts.security import hash_token
from thermolab.lab.clock import ManualClock
from thermolab.lab.db.login_models import ApiToken

from .conftest import PASSWORD, LabFactory
from .test_live import closed_with, login, make, receive, still_open


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


def bearer(token: str) -> dict[str, str]:
    return {"authorization": f"Bearer {token}"}


def test_a_token_is_shown_once_stored_hashed_and_acts_as_its_user(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        made = client.post("/api/tokens", headers=login(lab, "ana"), json={"name": "notebook"})
        assert made.status_code == 201, made.text
        body = made.json()
        secret = body["token"]
        assert secret.startswith("tlab_")
        assert body["prefix"] == secret[:12]
        assert body["readOnly"] is False
        assert body["name"] == "notebook"
        with lab.db.read() as session:
            stored = session.scalars(select(ApiToken.token_hash)).all()
        assert stored == [hash_token(secret)]  # the secret itself is nowhere
        listed = client.get("/api/tokens", headers=bearer(secret)).json()
        assert [t["name"] for t in listed] == ["notebook"]
        assert "token" not in listed[0]
        me = client.get("/api/session", headers=bearer(secret)).json()
        assert me["username"] == "ana"
        # Asking for control is a state change; a bearer request needs no Origin to pass.
        control = client.post("/api/rigs/twin/control", headers=bearer(secret))
        assert control.status_code == 200
        assert control.json()["access"]["role"] == "controller"
        # A cross-site page could not have made it: the cookie alone from there is refused.
        cross = {**login(lab, "ana"), "sec-fetch-site": "cross-site"}
        assert client.post("/api/rigs/twin/heartbeat", headers=cross).json()["code"] == (
            "cross_origin"
        )


def test_bearer_requests_are_judged_by_the_token_alone(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        # A made-up header next to a good cookie gets 401, not the cookie's rights.
        forged = {**login(lab, "ana"), **bearer("tlab_made_up"), "sec-fetch-site": "cross-site"}
        answer = client.post("/api/rigs/twin/control", headers=forged)
        assert answer.status_code == 401
        assert answer.json()["code"] == "not_authenticated"
        assert answer.headers["www-authenticate"].startswith("Bearer")
        assert client.get("/api/nothing-here", headers=forged).status_code == 401


def test_read_only_tokens_read_and_change_nothing(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        made = client.post(
            "/api/tokens", headers=login(lab, "ana"), json={"name": "viewer", "readOnly": True}
        ).json()
        reader = bearer(made["token"])
        assert client.get("/api/rigs", headers=reader).status_code == 200
        refused = client.post("/api/rigs/twin/control", headers=reader)
        assert refused.status_code == 403
        assert "read-only" in refused.json()["detail"]
        assert client.delete(f"/api/tokens/{made['id']}", headers=reader).status_code == 403


def test_tokens_cannot_change_passwords_or_mint_tokens(make_lab: LabFactory) -> None:
    lab, client, _ = make(make_lab)
    with client:
        full = client.post("/api/tokens", headers=login(lab, "tina"), json={"name": "admin"})
        token = bearer(full.json()["token"])
        changed = client.put(
            "/api/users/tina/password",
            headers=token,
            json={"password": "a brand new password", "currentPassword": PASSWORD},
        )
        assert changed.status_code == 403
        assert "log in with your password" in changed.text
        minted = client.post("/api/tokens", headers=token, json={"name": "another"})
        assert minted.status_code == 403
        # A teacher's token has a teacher's rights otherwise.
        assert client.get("/api/users", headers=token).status_code == 200


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"name": ""}, "name"),
        ({"name": "x" * 65}, "name"),
        ({"name": "ok", "days": 0}, "days"),
        ({"name": "ok", "days": 366}, "days"),
        ({"name": "ok", "readOnly": "yes"}, "readOnly"),
    ],
)
def test_bad_token_requests_are_422_naming_the_field(
    make_lab: LabFactory, body: dict[str, object], field: str
) -> None:
    lab, client, _ = make(make_lab)
    with client:
        answer = client.post("/api/tokens", headers=login(lab, "ana"), json=body)
        assert answer.status_code == 422
        assert answer.json()["code"] == "invalid_request"
        assert field in answer.json()["detail"]


def test_a_revoked_token_is_refused_at_once_and_its_sockets_closed(make_lab: LabFactory) -> None:
    lab, client, live = make(make_lab)
    live._session_check = 60.0  # the revocation itself closes them, not the periodic check
    with client:
        cookie = login(lab, "ana")
        one = client.post("/api/tokens", headers=cookie, json={"name": "one"}).json()
        two = client.post("/api/tokens", headers=cookie, json={"name": "two"}).json()
        with (
            client.websocket_connect("/api/rigs/twin/live", headers=bearer(one["token"])) as ws1,
            client.websocket_connect("/api/rigs/twin/live", headers=bearer(two["token"])) as ws2,
            client.websocket_connect("/api/rigs/twin/live", headers=cookie) as ws3,
        ):
            for ws in (ws1, ws2, ws3):
                assert receive(ws)["type"] == "hello"
            assert client.delete(f"/api/tokens/{one['id']}", headers=cookie).status_code == 204
            assert closed_with(ws1) == 4401
            assert still_open(ws2)
            assert still_open(ws3)
            gone = client.get("/api/rigs", headers=bearer(one["token"]))
            assert gone.status_code == 401
            assert "revoked" in gone.json()["detail"]
            assert client.get("/api/rigs", headers=bearer(two["token"])).status_code == 200
        # Someone else's token cannot be revoked (nor told apart from a missing one).
        assert client.delete(f"/api/tokens/{two['id']}", headers=login(lab, "ben")).status_code == (
            404
        )


def test_an_expired_token_is_refused_and_removing_the_account_closes_its_sockets(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab, client, live = make(make_lab)
    live._session_check = 60.0
    with client:
        made = client.post("/api/tokens", headers=login(lab, "ana"), json={"name": "x", "days": 1})
        token = bearer(made.json()["token"])
        with client.websocket_connect("/api/rigs/twin/live", headers=token) as ws:
            receive(ws)
            assert client.delete("/api/users/ana", headers=login(lab, "tina")).status_code == 204
            assert closed_with(ws) == 4401
        made = client.post("/api/tokens", headers=login(lab, "ben"), json={"name": "x", "days": 1})
        token = bearer(made.json()["token"])
        assert client.get("/api/rigs", headers=token).status_code == 200
        clock.advance(86401.0)
        assert client.get("/api/rigs", headers=token).status_code == 401


def test_the_lab_publishes_its_version_without_a_login(make_lab: LabFactory) -> None:
    _, client, _ = make(make_lab)
    with client:
        answer = client.get("/api/version").json()
        assert answer["name"] == "thermolab"
        assert answer["api"] == "1.0"
        assert "speedup" not in answer  # each rig's own: GET /api/rigs


def test_the_controllers_reading_is_fresh_and_keeps_its_turn_past_the_idle_limit(
    make_lab: LabFactory, clock: ManualClock
) -> None:
    lab, client, _ = make(make_lab)
    idle = lab.config.rig("twin").idle_limit
    assert idle is not None
    with client:
        ana, ben = login(lab, "ana"), login(lab, "ben")
        assert client.post("/api/rigs/twin/control", headers=ana).status_code == 200
        assert client.put("/api/rigs/twin/input", headers=ana, json={"u": 2.0}).status_code == 200
        mine = client.get("/api/rigs/twin/reading", headers=ana).json()
        assert mine["fresh"] is True
        assert mine["u"] == 2.0
        assert mine["unit"] == "V"
        theirs = client.get("/api/rigs/twin/reading", headers=ben).json()
        assert theirs["fresh"] is False  # a watcher gets the latest reading, no device I/O
        # A step test: the heater set once, then only reads, for longer than the idle limit.
        for _ in range(int(idle * 1.5 / 10)):
            clock.advance(10.0)  # within the client timeout: each read is a heartbeat too
            assert client.get("/api/rigs/twin/reading", headers=ana).json()["fresh"] is True
        assert client.get("/api/rigs/twin", headers=ana).json()["access"]["role"] == "controller"
        # Without reads or commands the idle limit still ends the turn.
        clock.advance(idle + 1)
        lab.sweep()
        assert client.get("/api/rigs/twin", headers=ana).json()["access"]["role"] != "controller"
        assert client.get("/api/rigs/nothing/reading", headers=ana).status_code == 404


def test_revoking_a_token_ends_the_turn_and_queue_place_it_asked_for_and_nothing_else(
    make_lab: LabFactory,
) -> None:
    lab, client, _ = make(make_lab)
    safe = lab.hub.published("twin").safe_input
    with client:
        ana, ben = login(lab, "ana"), login(lab, "ben")

        def role(who: dict[str, str]) -> str:
            return str(client.get("/api/rigs/twin", headers=who).json()["access"]["role"])

        def revoke(who: dict[str, str], token: dict[str, str]) -> None:
            assert client.delete(f"/api/tokens/{token['id']}", headers=who).status_code == 204

        def new_token(who: dict[str, str]) -> dict[str, str]:
            made = client.post("/api/tokens", headers=who, json={"name": "script"})
            assert made.status_code == 201
            return dict(made.json())

        # A login's turn is not a token's: revoking ana's token leaves her browser's turn.
        assert client.post("/api/rigs/twin/control", headers=ana).status_code == 200
        revoke(ana, new_token(ana))
        assert role(ana) == "controller"
        # A script waiting in the queue leaves it when its token is revoked.
        waiting = new_token(ben)
        asked = client.post("/api/rigs/twin/control", headers=bearer(waiting["token"]))
        assert asked.json()["access"]["role"] == "queued"
        revoke(ben, waiting)
        assert role(ben) == "watcher"
        # A script promoted from the queue holds its turn by its token, passed on with its place.
        script = new_token(ben)
        asked = client.post("/api/rigs/twin/control", headers=bearer(script["token"]))
        assert asked.status_code == 200
        assert client.delete("/api/rigs/twin/control", headers=ana).status_code == 200
        assert role(ben) == "controller"
        put = client.put("/api/rigs/twin/input", headers=bearer(script["token"]), json={"u": 7.0})
        assert put.status_code == 200
        assert lab.hub.applied("twin") == 7.0
        revoke(ben, script)  # at once: no sweep, no clock moved past the client timeout
        assert lab.hub.applied("twin") == safe
        assert role(ben) == "watcher"
        assert role(ana) == "watcher"
