"""The LTI 1.3 tool against a real (test) platform over HTTP: launches, refusals, services.

The platform (:mod:`.lti_platform`) has its own RSA keys, serves its JWKS,
signs id_tokens, checks the tool's signed assertions against the tool's JWKS,
and keeps a roster and a gradebook the tests read back. Both databases.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Iterator
from html import unescape
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from thermolab.lab.clock import ManualClock
from thermolab.lab.db.login_models import LoginSession
from thermolab.lab.db.lti_models import GradeStatus, LtiIdentity, LtiLoginState
from thermolab.lab.db.models import Course, CourseMember, User
from thermolab.lab.service import Lab

from .conftest import PASSWORD
from .lti_platform import INSTRUCTOR, LEARNER, PendingLaunch, Person, Platform

Client = Callable[..., TestClient]
TOOL = "https://testserver"


@pytest.fixture
def platform(lab: Lab) -> Iterator[Platform]:
    found = Platform(lab.lti.keys.jwks).start()
    found.tool_url = TOOL
    try:
        yield found
    finally:
        found.stop()


@pytest.fixture
def teacher(lab: Lab, app_client: Client) -> TestClient:
    lab.users.add("tess", PASSWORD, "teacher", admin=True)
    return app_client("tess", base_url=TOOL)


@pytest.fixture
def registered(teacher: TestClient, platform: Platform) -> int:
    answer = teacher.post("/api/lti/platforms", json=platform.registration())
    assert answer.status_code == 201, answer.text
    return int(answer.json()["id"])


def _launch(
    client: TestClient, platform: Platform, hint: str, *, with_cookie: bool = True
) -> httpx.Response:
    """The whole round trip: login initiation, the platform's authorisation, the launch."""
    start = client.get("/api/lti/login", params=platform.login_params(hint), follow_redirects=False)
    assert start.status_code == 302, start.text
    page = httpx.get(start.headers["location"]).text
    fields = dict(re.findall(r'name="([a-z_]+)" value="([^"]*)"', page))
    if not with_cookie:
        client.cookies.clear()
    return client.post(
        "/api/lti/launch",
        data={k: unescape(v) for k, v in fields.items()},
        follow_redirects=False,
    )


def _counts(lab: Lab) -> dict[str, int]:
    with lab.db.read() as session:
        return {
            model.__tablename__: int(session.scalar(select(func.count()).select_from(model)) or 0)
            for model in (User, Course, CourseMember, LoginSession, LtiIdentity)
        }


def test_a_learner_and_an_instructor_launch_and_are_signed_in(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    lab.users.add("ana.souza", PASSWORD, "student", "Ana Souza")  # made before, by a class list
    platform.expect(
        "h-ana",
        PendingLaunch(
            Person("sub-ana", "Ana S.", [LEARNER], "Ana.Souza"),
            custom={"thermolab_target": "rig:twin"},
        ),
    )
    platform.expect("h-ivo", PendingLaunch(Person("sub-ivo", "Ivo Prof", [INSTRUCTOR])))
    before = _counts(lab)

    ana = app_client(base_url=TOOL)
    answer = _launch(ana, platform, "h-ana")
    assert answer.status_code == 303, answer.text
    assert answer.headers["location"] == "/#/rig/twin"
    cookie = [
        c for c in answer.headers.get_list("set-cookie") if c.startswith("thermolab_session=")
    ]
    assert cookie
    assert "SameSite=None" in cookie[0]
    assert "Secure" in cookie[0]
    assert "Partitioned" in cookie[0]
    me = ana.get("/api/session").json()
    assert (me["username"], me["role"]) == ("ana.souza", "student")  # linked, not duplicated

    ivo = app_client(base_url=TOOL)
    assert _launch(ivo, platform, "h-ivo").status_code == 303
    assert ivo.get("/api/session").json()["role"] == "teacher"

    after = _counts(lab)
    assert after["users"] == before["users"] + 1  # Ivo only: Ana's account was linked
    assert after["courses"] == before["courses"] + 1  # the LMS context's course, once
    with lab.db.read() as session:
        course = session.scalars(select(Course)).one()
        assert course.title == "Controle de Processos"
        roles = dict(
            session.execute(
                select(User.username, CourseMember.role).join(
                    CourseMember, CourseMember.user_id == User.id
                )
            ).all()
        )
    assert roles["ana.souza"] == "student"
    assert roles[f"lti-{_digest(registered, 'sub-ivo')}"] == "teacher"

    # A second launch of Ana signs in the same account, in the same course.
    again = app_client(base_url=TOOL)
    assert _launch(again, platform, "h-ana").status_code == 303
    assert _counts(lab)["users"] == after["users"]


def test_a_teaching_assistant_launches_as_the_courses_assistant(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    assistant = "http://purl.imsglobal.org/vocab/lis/v2/membership/Instructor#TeachingAssistant"
    platform.expect("h-tea", PendingLaunch(Person("sub-tea", "Tea", [assistant])))
    tea = app_client(base_url=TOOL)
    assert _launch(tea, platform, "h-tea").status_code == 303
    assert tea.get("/api/session").json()["role"] == "student"  # the account: never a teacher's
    course = tea.get("/api/courses").json()
    assert len(course) == 1  # the LMS course's, which they assist
    members = tea.get(f"/api/courses/{course[0]['name']}").json()["members"]
    assert [m["role"] for m in members] == ["assistant"]
    assert tea.put(f"/api/courses/{course[0]['name']}/rigs", json={"rigs": []}).status_code == 403


def _digest(platform_id: int, sub: str) -> str:
    import hashlib

    return hashlib.sha256(f"{platform_id}\n{sub}".encode()).hexdigest()[:12]


@pytest.mark.parametrize(
    ("spoil", "code"),
    [
        ({"key": "forged"}, "lti_invalid_token"),
        ({"exp": -3600}, "lti_invalid_token"),
        ({"aud": "another-tool"}, "lti_invalid_token"),
        ({"deployment": "deployment-9"}, "lti_unknown_deployment"),
        ({"nonce": "not-the-login-nonce"}, "lti_invalid_token"),
    ],
)
def test_a_bad_id_token_is_refused_with_a_page_and_changes_nothing(
    lab: Lab,
    app_client: Client,
    platform: Platform,
    registered: int,
    spoil: dict[str, Any],
    code: str,
    caplog: pytest.LogCaptureFixture,
) -> None:
    if spoil.get("key") == "forged":
        from .lti_platform import _new_key

        spoil = {"key": _new_key()[0]}  # a key the platform never published
    platform.expect("h", PendingLaunch(Person("sub-x", "Xavier", [LEARNER]), spoil=spoil))
    before = _counts(lab)
    client = app_client(base_url=TOOL, headers={"Accept-Language": "pt-BR"})
    answer = _launch(client, platform, "h")
    assert answer.status_code == 400
    assert answer.headers["content-type"].startswith("text/html")
    assert f'<code id="lti-code">{code}</code>' in answer.text
    assert 'lang="pt-BR"' in answer.text
    assert "AVA" in answer.text
    assert "thermolab_session" not in answer.headers.get("set-cookie", "")
    assert _counts(lab) == before
    assert any(code in r.getMessage() for r in caplog.records)


def test_a_replayed_launch_and_an_unknown_platform_are_refused(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    platform.expect("h", PendingLaunch(Person("sub-r", "Rita", [LEARNER])))
    client = app_client(base_url=TOOL)
    start = client.get("/api/lti/login", params=platform.login_params("h"), follow_redirects=False)
    fields = dict(
        re.findall(r'name="([a-z_]+)" value="([^"]*)"', httpx.get(start.headers["location"]).text)
    )
    assert client.post("/api/lti/launch", data=fields, follow_redirects=False).status_code == 303
    before = _counts(lab)
    replay = client.post("/api/lti/launch", data=fields, follow_redirects=False)
    assert replay.status_code == 400
    assert '"lti-code">lti_replayed<' in replay.text
    assert _counts(lab) == before

    stranger = client.get(
        "/api/lti/login", params={**platform.login_params("h"), "iss": "https://lms.example"}
    )
    assert stranger.status_code == 400
    assert "lti_unknown_platform" in stranger.text


@pytest.mark.parametrize("path", ["/api/lti/login", "/api/lti/launch"])
def test_a_form_with_too_many_fields_is_refused_with_a_page(app_client: Client, path: str) -> None:
    client = app_client(base_url=TOOL)
    form = "&".join(f"field{i}=x" for i in range(60))
    answer = client.post(
        path,
        content=form,
        headers={"Content-Type": "application/x-www-form-urlencoded"},
        follow_redirects=False,
    )
    assert answer.status_code == 400, answer.text
    assert "lti_invalid_token" in answer.text
    assert "too many fields" in answer.text


def test_a_platform_whose_keys_cannot_be_fetched_is_refused(
    lab: Lab, app_client: Client, teacher: TestClient, platform: Platform
) -> None:
    body = platform.registration(jwks_url="http://127.0.0.1:9/jwks")  # nothing listens there
    assert teacher.post("/api/lti/platforms", json=body).status_code == 201
    platform.expect("h", PendingLaunch(Person("sub-j", "Jo", [LEARNER])))
    before = _counts(lab)
    answer = _launch(app_client(base_url=TOOL), platform, "h")
    assert answer.status_code == 502
    assert "lti_jwks_unreachable" in answer.text
    assert _counts(lab) == before


def test_the_platforms_key_rotation_is_followed(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    lab.lti.jwks.cooldown = 0  # the platform rotates at once here, not 10 s later
    platform.expect("h", PendingLaunch(Person("sub-k", "Kim", [LEARNER])))
    assert _launch(app_client(base_url=TOOL), platform, "h").status_code == 303
    platform.rotate()  # the cached key set no longer has the new kid: fetched again
    assert _launch(app_client(base_url=TOOL), platform, "h").status_code == 303


def test_without_the_state_cookie_the_launch_opens_in_a_new_window(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    platform.expect(
        "h",
        PendingLaunch(
            Person("sub-n", "Nina", [LEARNER]), custom={"thermolab_target": "guide:twin/theory"}
        ),
    )
    client = app_client(base_url=TOOL)
    page = _launch(client, platform, "h", with_cookie=False)
    assert page.status_code == 200
    assert 'id="lti-new-window"' in page.text
    assert "thermolab_session" not in page.headers.get("set-cookie", "")
    link = unescape(
        re.search(r'href="([^"]+)"', page.text.split('id="lti-new-window"')[1]).group(1)
    )  # type: ignore[union-attr]
    window = app_client(base_url=TOOL)
    opened = window.get(link.removeprefix(TOOL), follow_redirects=False)
    assert opened.status_code == 303
    assert opened.headers["location"] == "/#/rig/twin?guide=theory"
    assert window.get("/api/session").json()["role"] == "student"
    used = window.get(link.removeprefix(TOOL), follow_redirects=False)
    assert used.status_code == 400
    assert "lti_state_invalid" in used.text


def test_the_tools_keys_are_published_and_rotated(
    lab: Lab, app_client: Client, teacher: TestClient
) -> None:
    first = app_client().get("/api/lti/jwks").json()["keys"]
    assert len(first) == 1
    assert first[0]["kty"] == "RSA"
    assert "d" not in first[0]
    rotated = teacher.post("/api/lti/keys/rotate").json()["kid"]
    keys = [k["kid"] for k in app_client().get("/api/lti/jwks").json()["keys"]]
    assert keys == [rotated, first[0]["kid"]]  # the old one stays published a while
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    clock.advance(8 * 24 * 3600)
    assert [k["kid"] for k in app_client().get("/api/lti/jwks").json()["keys"]] == [rotated]


def test_registration_is_for_teachers_and_checks_its_urls(
    lab: Lab, app_client: Client, teacher: TestClient, platform: Platform
) -> None:
    lab.users.add("stu", PASSWORD, "student")
    student = app_client("stu", base_url=TOOL)
    assert student.post("/api/lti/platforms", json=platform.registration()).status_code == 403
    bad = {**platform.registration(), "tokenUrl": "http://lms.example/token"}
    answer = teacher.post("/api/lti/platforms", json=bad)
    assert answer.status_code == 422
    assert "https://" in answer.json()["detail"]
    assert teacher.post("/api/lti/platforms", json=platform.registration()).status_code == 201
    assert teacher.post("/api/lti/platforms", json=platform.registration()).status_code == 409
    tool = teacher.get("/api/lti/tool").json()
    assert tool["launchUrl"] == f"{TOOL}/api/lti/launch"
    # The platform may frame the lab now.
    policy = teacher.get("/api/lti/jwks").headers["content-security-policy"]
    assert f"frame-ancestors 'self' {platform.url}" in policy


def test_deep_linking_round_trip(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    platform.expect(
        "dl",
        PendingLaunch(Person("sub-t", "Teo", [INSTRUCTOR]), message_type="LtiDeepLinkingRequest"),
    )
    client = app_client(base_url=TOOL)
    answer = _launch(client, platform, "dl")
    assert answer.status_code == 303
    key = answer.headers["location"].removeprefix("/#/lti/deep-link/")
    offer = client.get(f"/api/lti/deep-links/{key}").json()
    targets = [i["target"] for i in offer["items"]]
    assert "rig:twin" in targets
    assert "guide:twin/theory" in targets
    page = client.post(
        f"/api/lti/deep-links/{key}",
        content="target=rig%3Atwin&target=guide%3Atwin%2Ftheory",
        headers={"Content-Type": "application/x-www-form-urlencoded"},
    )
    assert page.status_code == 200
    assert f"form-action {platform.url}" in page.headers["content-security-policy"]
    jwt_value = re.search(r'name="JWT" value="([^"]+)"', page.text).group(1)  # type: ignore[union-attr]
    back = httpx.post(f"{platform.url}/deep-link-return", data={"JWT": jwt_value})
    assert back.status_code == 200
    assert [i["custom"]["thermolab_target"] for i in platform.deep_link_items] == [
        "rig:twin",
        "guide:twin/theory",
    ]
    assert all(i["url"] == f"{TOOL}/api/lti/launch" for i in platform.deep_link_items)
    # Used once.
    assert client.get(f"/api/lti/deep-links/{key}").status_code == 404
    # A learner may not deep-link.
    platform.expect(
        "dl2",
        PendingLaunch(Person("sub-l", "Lia", [LEARNER]), message_type="LtiDeepLinkingRequest"),
    )
    assert _launch(app_client(base_url=TOOL), platform, "dl2").status_code == 400


def test_roster_sync_adds_and_removes(
    lab: Lab, app_client: Client, teacher: TestClient, platform: Platform, registered: int
) -> None:
    lab.users.add("bia", PASSWORD, "student")  # made before: linked by name, not copied
    platform.expect("h", PendingLaunch(Person("sub-ivo", "Ivo", [INSTRUCTOR])))
    assert _launch(app_client(base_url=TOOL), platform, "h").status_code == 303
    with lab.db.read() as session:
        course = session.scalars(select(Course.name)).one()
    platform.roster = [
        Person("sub-ivo", "Ivo", [INSTRUCTOR]),
        Person("sub-bia", "Bia", [LEARNER], "BIA"),
        Person("sub-caio", "Caio", [LEARNER], "caio"),
    ]
    first = teacher.post(f"/api/lti/courses/{course}/roster")
    assert first.status_code == 200, first.text
    assert first.json() == {"added": ["bia", "caio"], "removed": [], "kept": 1}
    users = _counts(lab)["users"]
    platform.roster = [
        platform.roster[0],
        platform.roster[2],
        Person("sub-dani", "Dani", [LEARNER]),
    ]
    second = teacher.post(f"/api/lti/courses/{course}/roster").json()
    assert (second["added"], second["removed"]) == (
        [f"lti-{_digest(registered, 'sub-dani')}"],
        ["bia"],
    )
    assert _counts(lab)["users"] == users + 1
    with lab.db.read() as session:
        assert session.scalar(select(User.id).where(User.username == "bia")) is not None  # kept
    assert teacher.post("/api/lti/courses/nope/roster").status_code == 404


def test_a_grade_is_posted_retried_and_read_back(
    lab: Lab, teacher: TestClient, platform: Platform, registered: int
) -> None:
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    item = f"{platform.url}/lineitems/1"
    platform.fail_scores = 1  # the gradebook is busy once
    grade = lab.lti.queue_grade(
        platform_id=registered, lineitem_url=item, sub="sub-ana", score_given=8.5, score_maximum=10
    )
    assert lab.lti.grades.deliver_due() == 0
    listed = {g["id"]: g for g in teacher.get("/api/lti/grades").json()}
    assert listed[grade]["status"] == "pending"
    assert "503" in listed[grade]["lastError"]
    assert lab.lti.grades.deliver_due() == 0  # not due yet: backing off
    clock.advance(31)
    assert lab.lti.grades.deliver_due() == 1
    score = platform.gradebook[("/lineitems/1", "sub-ana")]
    assert (score["scoreGiven"], score["scoreMaximum"]) == (8.5, 10.0)
    assert score["gradingProgress"] == "FullyGraded"
    assert teacher.get("/api/lti/grades").json()[0]["status"] == "sent"
    # A changed mark is queued again and wins.
    lab.lti.queue_grade(
        platform_id=registered, lineitem_url=item, sub="sub-ana", score_given=9, score_maximum=10
    )
    assert lab.lti.grades.deliver_due() == 1
    assert platform.gradebook[("/lineitems/1", "sub-ana")]["scoreGiven"] == 9.0


def test_a_grade_that_keeps_failing_is_marked_failed_and_can_be_retried(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    platform.fail_scores = 100
    grade = lab.lti.queue_grade(
        platform_id=registered,
        lineitem_url=f"{platform.url}/lineitems/2",
        sub="s",
        score_given=1,
        score_maximum=2,
    )
    for _ in range(8):
        lab.lti.grades.deliver_due()
        clock.advance(3600)
    teacher = app_client("tess", base_url=TOOL)  # hours later: a new login
    listed = teacher.get("/api/lti/grades").json()
    assert [(g["status"], g["attempts"]) for g in listed] == [("failed", 8)]
    assert "HTTP 503" in listed[0]["lastError"]
    platform.fail_scores = 0
    assert teacher.post(f"/api/lti/grades/{grade}/retry").json()["status"] == "pending"
    # The retry wakes the outbox's own thread, which posts it.
    deadline = time.monotonic() + 20
    while lab.lti.grades.list()[0].status is not GradeStatus.SENT:
        assert time.monotonic() < deadline, lab.lti.grades.list()
        time.sleep(0.05)
    assert platform.gradebook[("/lineitems/2", "s")]["scoreGiven"] == 1.0
    with pytest.raises(ValueError, match="from 0 to 2"):
        lab.lti.queue_grade(
            platform_id=registered,
            lineitem_url=f"{platform.url}/x",
            sub="s",
            score_given=3,
            score_maximum=2,
        )


def test_login_states_expire(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    platform.expect("h", PendingLaunch(Person("sub-e", "Eva", [LEARNER])))
    client = app_client(base_url=TOOL)
    start = client.get("/api/lti/login", params=platform.login_params("h"), follow_redirects=False)
    fields = dict(
        re.findall(r'name="([a-z_]+)" value="([^"]*)"', httpx.get(start.headers["location"]).text)
    )
    clock.advance(11 * 60)
    late = client.post("/api/lti/launch", data=fields, follow_redirects=False)
    assert late.status_code == 400
    assert "lti_state_invalid" in late.text
    assert lab.lti.launches.purge_expired() == 1
    with lab.db.read() as session:
        assert session.scalar(select(func.count()).select_from(LtiLoginState)) == 0


def test_one_state_signs_in_once_even_when_launches_race(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    from concurrent.futures import ThreadPoolExecutor

    from thermolab.lab.lti.errors import LtiReplayError

    platform.expect("h", PendingLaunch(Person("sub-race", "Rui", [LEARNER])))
    client = app_client(base_url=TOOL)
    start = client.get("/api/lti/login", params=platform.login_params("h"), follow_redirects=False)
    page = httpx.get(start.headers["location"]).text
    fields = {k: unescape(v) for k, v in re.findall(r'name="([a-z_]+)" value="([^"]*)"', page)}

    def launch(_: int) -> str:
        try:
            lab.lti.launches.complete(fields["id_token"], fields["state"], fields["state"])
        except LtiReplayError:
            return "replayed"
        return "signed in"

    with ThreadPoolExecutor(max_workers=6) as pool:
        outcomes = sorted(pool.map(launch, range(6)))
    assert outcomes == ["replayed"] * 5 + ["signed in"]
    with lab.db.read() as session:
        assert session.scalar(select(func.count()).select_from(LtiIdentity)) == 1


def test_a_users_mark_goes_to_the_lms_activity_that_links_its_target(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    target = "rig:twin"  # an assignment's target is "assignment:<id>" the same way
    platform.expect(
        "h",
        PendingLaunch(
            Person("sub-m", "Mia", [LEARNER], "mia"), custom={"thermolab_target": target}
        ),
    )
    assert _launch(app_client(base_url=TOOL), platform, "h").status_code == 303
    with lab.db.read() as session:
        mia = session.scalars(select(User.id).where(User.username == "mia")).one()
    assert (
        lab.lti.queue_grade_for_user(
            user_id=mia, target="rig:other", score_given=1, score_maximum=1
        )
        == []
    )
    queued = lab.lti.queue_grade_for_user(
        user_id=mia, target=target, score_given=7, score_maximum=10
    )
    assert len(queued) == 1
    assert lab.lti.grades.deliver_due() == 1
    assert platform.gradebook[("/lineitems/1", "sub-m")]["scoreGiven"] == 7.0


@pytest.mark.parametrize("issuer", ["https://lms.example/\x00", "https://lms.example/" + "x" * 300])
def test_a_login_with_a_nul_or_an_overlong_issuer_is_refused_not_a_server_error(
    lab: Lab, app_client: Client, issuer: str
) -> None:
    answer = app_client(base_url=TOOL).post(
        "/api/lti/login",
        data={"iss": issuer, "login_hint": "h", "target_link_uri": f"{TOOL}/api/lti/launch"},
        follow_redirects=False,
    )
    assert answer.status_code == 400
    assert "lti-code" in answer.text
