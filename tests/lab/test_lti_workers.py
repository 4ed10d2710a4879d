"""A launch's state is the database's: it starts on one web worker and ends on another.

Two labs (two apps, as two ``thermolab serve --workers`` processes) on one
database, each with its own memory; a browser whose requests a load balancer
sends to either. A deep-linking launch begun on one is chosen and answered on
the other, once; a new window's ticket made on one opens on the other, once,
and not after its two minutes; twenty takes of one key racing on two labs get it
once. Both databases. (The login-initiation
throttle shared in Redis: ``test_shared_limits.py``.)
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable, Iterator
from datetime import timedelta
from html import unescape

import httpx
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from thermolab.lab.clock import ManualClock
from thermolab.lab.db.lti_models import HandoffKind
from thermolab.lab.db.models import User
from thermolab.lab.http.app import create_app
from thermolab.lab.service import Lab

from .conftest import LabFactory
from .lti_platform import INSTRUCTOR, LEARNER, PendingLaunch, Person, Platform
from .test_lti import TOOL, platform, registered, teacher

__all__ = ["platform", "registered", "teacher"]  # the fixtures, shared with test_lti

Client = Callable[..., TestClient]


@pytest.fixture
def other_worker(make_lab: LabFactory, lab: Lab) -> Iterator[TestClient]:
    """A second lab on the same database, served by an app of its own."""
    second = make_lab()
    assert second.db is not lab.db
    with TestClient(create_app(second.config, lab=second, sweep_interval=None), base_url=TOOL) as c:
        yield c


def _move(browser: TestClient, to: TestClient) -> TestClient:
    """The browser's next request goes to ``to`` (its cookies go along)."""
    to.cookies.clear()
    for cookie in browser.cookies.jar:
        to.cookies.set(cookie.name, cookie.value or "", cookie.domain, cookie.path)
    return to


def _login_and_launch(
    first: TestClient, second: TestClient, platform: Platform, hint: str
) -> httpx.Response:
    """Login initiation on ``first``, the launch on ``second`` (the state is the database's)."""
    start = first.get("/api/lti/login", params=platform.login_params(hint), follow_redirects=False)
    assert start.status_code == 302, start.text
    page = httpx.get(start.headers["location"]).text
    fields = dict(re.findall(r'name="([a-z_]+)" value="([^"]*)"', page))
    return _move(first, second).post(
        "/api/lti/launch",
        data={k: unescape(v) for k, v in fields.items()},
        follow_redirects=False,
    )


def test_a_deep_link_begun_on_one_worker_is_answered_on_the_other_once(
    app_client: Client, other_worker: TestClient, platform: Platform, registered: int
) -> None:
    platform.expect(
        "dl",
        PendingLaunch(Person("sub-t", "Teo", [INSTRUCTOR]), message_type="LtiDeepLinkingRequest"),
    )
    here = app_client(base_url=TOOL)
    launched = _login_and_launch(here, other_worker, platform, "dl")
    assert launched.status_code == 303, launched.text
    key = launched.headers["location"].removeprefix("/#/lti/deep-link/")
    offer = _move(other_worker, here).get(f"/api/lti/deep-links/{key}")
    assert offer.status_code == 200, offer.text
    assert "rig:twin" in [i["target"] for i in offer.json()["items"]]
    page = _move(here, other_worker).post(
        f"/api/lti/deep-links/{key}",
        content="target=rig%3Atwin",
        headers={"Content-Type": "application/x-www-form-urlencoded"},
    )
    assert page.status_code == 200, page.text
    jwt_value = re.search(r'name="JWT" value="([^"]+)"', page.text).group(1)  # type: ignore[union-attr]
    assert (
        httpx.post(f"{platform.url}/deep-link-return", data={"JWT": jwt_value}).status_code == 200
    )
    assert [i["custom"]["thermolab_target"] for i in platform.deep_link_items] == ["rig:twin"]
    # Used: neither worker offers or answers it again.
    for worker in (here, other_worker):
        browser = _move(other_worker if worker is here else here, worker)
        assert browser.get(f"/api/lti/deep-links/{key}").status_code == 404
        again = browser.post(
            f"/api/lti/deep-links/{key}",
            content="target=rig%3Atwin",
            headers={"Content-Type": "application/x-www-form-urlencoded"},
        )
        assert again.status_code == 404
    # Nor to another teacher of the same lab.
    platform.expect(
        "dl2",
        PendingLaunch(Person("sub-u", "Uma", [INSTRUCTOR]), message_type="LtiDeepLinkingRequest"),
    )
    second_key = (
        _login_and_launch(app_client(base_url=TOOL), other_worker, platform, "dl2")
        .headers["location"]
        .removeprefix("/#/lti/deep-link/")
    )
    assert _move(here, other_worker).get(f"/api/lti/deep-links/{second_key}").status_code == 404


def _ticket(worker: TestClient, platform: Platform, hint: str) -> str:
    """A launch in a frame without cookies on ``worker``: the new window's link."""
    start = worker.get("/api/lti/login", params=platform.login_params(hint), follow_redirects=False)
    page = httpx.get(start.headers["location"]).text
    fields = dict(re.findall(r'name="([a-z_]+)" value="([^"]*)"', page))
    worker.cookies.clear()  # the frame's cookies are blocked
    handover = worker.post(
        "/api/lti/launch",
        data={k: unescape(v) for k, v in fields.items()},
        follow_redirects=False,
    )
    assert handover.status_code == 200, handover.text
    link = re.search(r'href="([^"]+)"', handover.text.split('id="lti-new-window"')[1])
    assert link is not None
    return unescape(link.group(1)).removeprefix(TOOL)


def test_a_ticket_made_on_one_worker_opens_on_the_other_once_and_expires(
    lab: Lab,
    app_client: Client,
    other_worker: TestClient,
    platform: Platform,
    registered: int,
) -> None:
    platform.expect(
        "w",
        PendingLaunch(
            Person("sub-n", "Nina", [LEARNER]), custom={"thermolab_target": "guide:twin/theory"}
        ),
    )
    link = _ticket(app_client(base_url=TOOL), platform, "w")
    opened = other_worker.get(link, follow_redirects=False)
    assert opened.status_code == 303, opened.text
    assert opened.headers["location"] == "/#/rig/twin?guide=theory"
    session = other_worker.get("/api/session").json()
    assert (session["displayName"], session["role"]) == ("Nina", "student")
    again = app_client(base_url=TOOL).get(link, follow_redirects=False)
    assert again.status_code == 400
    assert "lti_state_invalid" in again.text
    # A ticket not used within its two minutes opens nothing, on either worker.
    late = _ticket(app_client(base_url=TOOL), platform, "w")
    clock = lab.clock
    assert isinstance(clock, ManualClock)
    clock.advance(121)
    assert other_worker.get(late, follow_redirects=False).status_code == 400


def test_one_key_taken_by_racing_workers_is_given_once(
    make_lab: LabFactory, lab: Lab, registered: int
) -> None:
    other = make_lab()
    with lab.db.read() as session:
        teacher_id = session.scalar(select(User.id).where(User.username == "tess"))
    assert teacher_id is not None
    key = lab.lti.handoffs.put(
        HandoffKind.WINDOW, teacher_id, registered, {"path": "/#/"}, timedelta(minutes=2)
    )
    start = threading.Barrier(20)
    got: list[object] = []

    def take(i: int) -> None:
        start.wait()
        got.append((lab, other)[i % 2].lti.handoffs.take(HandoffKind.WINDOW, key))

    threads = [threading.Thread(target=take, args=(i,)) for i in range(20)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    assert len(got) == 20
    assert sum(found is not None for found in got) == 1
