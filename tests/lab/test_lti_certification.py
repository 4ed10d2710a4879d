"""The IMS LTI 1.3 certification guide's valid and known-bad launches, replayed (issue #25).

Each known-bad launch is made by the test platform (:mod:`.lti_platform`)
with one claim taken out or spoiled; the tool must answer the LTI error page
with the claim's specific code, log the refusal and create nothing. The valid
ones (learner, instructor, no roles at all but an empty list, deep linking
with one item, in a window) must sign the person in. SQLite only: the claims'
checks happen before the database is touched.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from thermolab.lab.db.login_models import LoginSession
from thermolab.lab.db.lti_models import LtiIdentity, LtiLoginState
from thermolab.lab.db.models import Course, CourseMember, User
from thermolab.lab.service import Lab

from .conftest import PASSWORD
from .lti_platform import INSTRUCTOR, LEARNER, PendingLaunch, Person, Platform

Client = Callable[..., TestClient]
TOOL = "https://testserver"
DEEP = "LtiDeepLinkingRequest"


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


@pytest.fixture
def platform(lab: Lab, app_client: Client) -> Iterator[Platform]:
    found = Platform(lab.lti.keys.jwks).start()
    found.tool_url = TOOL
    lab.users.add("root", PASSWORD, "teacher", admin=True)
    answer = app_client("root", base_url=TOOL).post("/api/lti/platforms", json=found.registration())
    assert answer.status_code == 201, answer.text
    try:
        yield found
    finally:
        found.stop()


def _launch(client: TestClient, platform: Platform, hint: str) -> httpx.Response:
    start = client.get("/api/lti/login", params=platform.login_params(hint), follow_redirects=False)
    assert start.status_code == 302, start.text
    page = httpx.get(start.headers["location"]).text
    fields = dict(re.findall(r'name="([a-z_]+)" value="([^"]*)"', page))
    return client.post("/api/lti/launch", data=fields, follow_redirects=False)


def _counts(lab: Lab) -> dict[str, int]:
    with lab.db.read() as session:
        return {
            model.__tablename__: int(session.scalar(select(func.count()).select_from(model)) or 0)
            for model in (User, Course, CourseMember, LoginSession, LtiIdentity)
        }


# (what the certification guide calls it, message type, roles, spoil, expected code)
KNOWN_BAD: list[tuple[str, str, list[str], dict[str, Any], str]] = [
    ("no roles claim", "LtiResourceLinkRequest", [LEARNER], {"drop": ["roles"]}, "claim"),
    ("roles not a list", "LtiResourceLinkRequest", [], {"claims": {"roles": LEARNER}}, "claim"),
    ("no resource_link", "LtiResourceLinkRequest", [LEARNER], {"drop": ["resource_link"]}, "claim"),
    (
        "resource_link without id",
        "LtiResourceLinkRequest",
        [LEARNER],
        {"claims": {"resource_link": {"title": "x"}}},
        "claim",
    ),
    (
        "resource_link id empty",
        "LtiResourceLinkRequest",
        [LEARNER],
        {"claims": {"resource_link": {"id": ""}}},
        "claim",
    ),
    (
        "target_link_uri on another host",
        "LtiResourceLinkRequest",
        [LEARNER],
        {"claims": {"target_link_uri": "https://evil.example/api/lti/launch"}},
        "target",
    ),
    (
        "no target_link_uri",
        "LtiResourceLinkRequest",
        [LEARNER],
        {"drop": ["target_link_uri"]},
        "claim",
    ),
    ("no message_type", "LtiResourceLinkRequest", [LEARNER], {"drop": ["message_type"]}, "token"),
    (
        "wrong version",
        "LtiResourceLinkRequest",
        [LEARNER],
        {"claims": {"version": "1.2.0"}},
        "token",
    ),
    ("no deployment_id", "LtiResourceLinkRequest", [LEARNER], {"drop": ["deployment_id"]}, "token"),
    ("unknown deployment", "LtiResourceLinkRequest", [LEARNER], {"deployment": "x"}, "deployment"),
    ("deep link by a learner", DEEP, [LEARNER], {}, "token"),
    (
        "deep link accepting only 'link'",
        DEEP,
        [INSTRUCTOR],
        {"dl_settings": {"accept_types": ["link"]}},
        "claim",
    ),
    (
        "deep link showing only embedded",
        DEEP,
        [INSTRUCTOR],
        {"dl_settings": {"accept_presentation_document_targets": ["embed"]}},
        "claim",
    ),
    (
        "deep link without a return URL",
        DEEP,
        [INSTRUCTOR],
        {"dl_settings": {"deep_link_return_url": None}},
        "claim",
    ),
    ("deep link without settings", DEEP, [INSTRUCTOR], {"drop": []}, "claim"),
]
CODES = {
    "claim": "lti_claim_invalid",
    "target": "lti_target_invalid",
    "token": "lti_invalid_token",
    "deployment": "lti_unknown_deployment",
}


def _without_settings(platform: Platform) -> Callable[[PendingLaunch, str, str], str]:
    """The platform's id_token with the deep-linking settings claim taken out."""
    import jwt

    original = platform.id_token

    def make(launch: PendingLaunch, nonce: str, redirect: str) -> str:
        claims = jwt.decode(original(launch, nonce, redirect), options={"verify_signature": False})
        claims.pop("https://purl.imsglobal.org/spec/lti-dl/claim/deep_linking_settings")
        headers = {"kid": platform._jwk["kid"]}
        return jwt.encode(claims, platform._key, algorithm="RS256", headers=headers)

    return make


def test_every_known_bad_launch_gets_its_error_page_and_creates_nothing(
    lab: Lab, app_client: Client, platform: Platform, caplog: pytest.LogCaptureFixture
) -> None:
    """One lab, every case of the guide's list in turn (seconds, not a lab per case)."""
    wrong: list[str] = []
    original = platform.id_token
    for number, (name, kind, roles, spoil, code) in enumerate(KNOWN_BAD):
        hint = f"bad-{number}"
        if spoil == {"drop": []}:  # the deep-linking settings claim itself taken out
            platform.id_token = _without_settings(platform)  # type: ignore[method-assign]
        platform.expect(hint, PendingLaunch(Person(f"sub-{hint}", "Bad", roles), kind, spoil=spoil))
        before = _counts(lab)
        caplog.clear()
        answer = _launch(app_client(base_url=TOOL), platform, hint)
        platform.id_token = original  # type: ignore[method-assign]
        expected = f'<code id="lti-code">{CODES[code]}</code>'
        if (
            answer.status_code != 400
            or not answer.headers["content-type"].startswith("text/html")
            or expected not in answer.text
            or "thermolab_session" in answer.headers.get("set-cookie", "")
        ):
            wrong.append(f"{name}: {answer.status_code} {answer.text[-300:]}")
        elif _counts(lab) != before:
            wrong.append(f"{name}: the refused launch created rows")
        elif not any(CODES[code] in r.getMessage() for r in caplog.records):
            wrong.append(f"{name}: the refusal was not logged")
    assert wrong == [], "\n".join(wrong)


def test_valid_resource_link_launches_sign_the_person_in(
    lab: Lab, app_client: Client, platform: Platform
) -> None:
    for sub, roles, home in (
        ("sub-learner", [LEARNER], "student"),
        ("sub-instructor", [INSTRUCTOR], "teacher"),
        ("sub-nobody", [], "student"),  # an empty list of roles is valid
    ):
        platform.expect(sub, PendingLaunch(Person(sub, "Ok", roles)))
        answer = _launch(app_client(base_url=TOOL), platform, sub)
        assert answer.status_code == 303, answer.text
        with lab.db.read() as session:
            user = session.scalar(
                select(User)
                .join(LtiIdentity, LtiIdentity.user_id == User.id)
                .where(LtiIdentity.sub == sub)
            )
            assert user is not None
            # An LMS never makes a lab administrator, whatever roles it sends.
            assert (user.role, user.admin) == (home, False)


def test_deep_linking_honours_accept_multiple_and_the_presentation_targets(
    lab: Lab, app_client: Client, platform: Platform
) -> None:
    settings = {"accept_multiple": False, "accept_presentation_document_targets": ["window"]}
    platform.expect(
        "dl",
        PendingLaunch(Person("sub-t", "Teo", [INSTRUCTOR]), DEEP, spoil={"dl_settings": settings}),
    )
    client = app_client(base_url=TOOL)
    answer = _launch(client, platform, "dl")
    assert answer.status_code == 303, answer.text
    key = answer.headers["location"].removeprefix("/#/lti/deep-link/")
    assert client.get(f"/api/lti/deep-links/{key}").json()["acceptMultiple"] is False
    form = {"Content-Type": "application/x-www-form-urlencoded"}
    two = client.post(
        f"/api/lti/deep-links/{key}",
        content="target=rig%3Atwin&target=guide%3Atwin%2Ftheory",
        headers=form,
    )
    assert two.status_code == 422
    one = client.post(f"/api/lti/deep-links/{key}", content="target=rig%3Atwin", headers=form)
    assert one.status_code == 200, one.text
    jwt_value = re.search(r'name="JWT" value="([^"]+)"', one.text).group(1)  # type: ignore[union-attr]
    assert (
        httpx.post(f"{platform.url}/deep-link-return", data={"JWT": jwt_value}).status_code == 200
    )
    [item] = platform.deep_link_items
    assert item["type"] == "ltiResourceLink"
    assert item["window"] == {"targetName": "thermolab"}
    assert "iframe" not in item


def test_a_login_initiation_for_another_host_is_refused_and_stores_no_state(
    lab: Lab, app_client: Client, platform: Platform
) -> None:
    params = {**platform.login_params("x"), "target_link_uri": "https://evil.example/launch"}
    answer = app_client(base_url=TOOL).get("/api/lti/login", params=params)
    assert answer.status_code == 400
    assert '"lti-code">lti_target_invalid<' in answer.text
    with lab.db.read() as session:
        assert session.scalar(select(func.count()).select_from(LtiLoginState)) == 0


def test_login_initiation_is_throttled_per_address(
    lab: Lab, app_client: Client, platform: Platform
) -> None:
    client = app_client(base_url=TOOL)
    statuses = [
        client.get(
            "/api/lti/login", params=platform.login_params("t"), follow_redirects=False
        ).status_code
        for _ in range(40)
    ]
    assert statuses[:30] == [302] * 30
    assert set(statuses[30:]) == {429}
    with lab.db.read() as session:
        assert session.scalar(select(func.count()).select_from(LtiLoginState)) == 30


@pytest.mark.parametrize("path", ["/api/lti/login", "/api/lti/launch"])
def test_an_oversized_form_gets_the_lti_page_and_is_logged(
    app_client: Client, path: str, caplog: pytest.LogCaptureFixture
) -> None:
    body = "id_token=" + "a" * (80 * 1024) + "&state=s"
    answer = app_client(base_url=TOOL).post(
        path,
        content=body,
        headers={"Content-Type": "application/x-www-form-urlencoded"},
        follow_redirects=False,
    )
    assert answer.status_code == 413
    assert answer.headers["content-type"].startswith("text/html")
    assert '"lti-code">lti_form_too_large<' in answer.text
    assert any("lti_form_too_large" in r.getMessage() for r in caplog.records)
