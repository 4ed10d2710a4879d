"""Assignments through LTI against the test platform: deep linked, launched, marked, graded.

A teacher in the LMS links an assignment of their course; a learner launches
the link, makes a real twin run, hands it in; the mark reaches the platform's
gradebook over HTTP (read back), a re-hand-in replaces it, a failed post is
retried and shown to the teacher. Both databases.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from thermolab.lab.accounts.users import Principal
from thermolab.lab.db.models import Course, CourseMember, User
from thermolab.lab.service import Lab

from .conftest import PASSWORD, LabFactory
from .lti_platform import INSTRUCTOR, LEARNER, PendingLaunch, Person, Platform
from .test_assignments import _assignment, _run
from .test_lti import TOOL, _launch, platform, registered, teacher
from .test_runs import twin_lab

# On SQLite alone: the LMS exchange; LTI's nonces and platforms on both are test_lti
# (tests/lab/conftest.py says why).
pytestmark = pytest.mark.sqlite_only

__all__ = ["platform", "registered", "teacher"]  # the fixtures, shared with test_lti

Client = Callable[..., TestClient]
ITEM = "/lineitems/1"


@pytest.fixture
def lab(make_lab: LabFactory) -> Lab:
    return twin_lab(make_lab)


def _principal(lab: Lab, username: str) -> Principal:
    with lab.db.read() as session:
        user = session.scalars(select(User).where(User.username == username)).one()
        return Principal(user.id, user.username, user.role)


def _until(check: Callable[[], Any], lab: Lab, what: str) -> Any:
    """Deliver due grades until ``check()`` is truthy (the outbox's own thread may be first)."""
    deadline = time.monotonic() + 30
    while not (found := check()):
        assert time.monotonic() < deadline, (what, lab.lti.grades.list())
        lab.lti.grades.deliver_due()
        time.sleep(0.05)
    return found


def _deep_link_an_assignment(
    lab: Lab, app_client: Client, platform: Platform
) -> tuple[TestClient, int, dict[str, Any]]:
    """An instructor's deep-linking launch, an assignment set in that course, linked."""
    platform.expect(
        "dl",
        PendingLaunch(
            Person("sub-ivo", "Ivo Prof", [INSTRUCTOR]), message_type="LtiDeepLinkingRequest"
        ),
    )
    ivo = app_client(base_url=TOOL)
    answer = _launch(ivo, platform, "dl")
    assert answer.status_code == 303, answer.text
    key = answer.headers["location"].removeprefix("/#/lti/deep-link/")
    with lab.db.read() as session:
        course = session.scalars(select(Course.name)).one()  # the LMS course's lab course
    made = ivo.post(
        f"/api/courses/{course}/assignments", json=_assignment(methods=["lsm"], settings={})
    )
    assert made.status_code == 201, made.text
    assignment = int(made.json()["id"])
    # Another course's assignment is not on offer.
    lab.users.add("tina", PASSWORD, "teacher")
    lab.courses.create("elsewhere", "Elsewhere", "tina")
    other = app_client("tina", base_url=TOOL).post(
        "/api/courses/elsewhere/assignments", json=_assignment()
    )
    assert other.status_code == 201, other.text
    offer = ivo.get(f"/api/lti/deep-links/{key}").json()
    offered = {i["target"]: i for i in offer["items"]}
    assert f"assignment:{other.json()['id']}" not in offered
    assert offered[f"assignment:{assignment}"]["kind"] == "assignment"
    assert offered[f"assignment:{assignment}"]["title"] == "Step response of the box"
    assert "rig:twin" in offered  # rigs and guide pages stay on offer
    page = ivo.post(
        f"/api/lti/deep-links/{key}",
        content=f"target=assignment%3A{assignment}",
        headers={"Content-Type": "application/x-www-form-urlencoded"},
    )
    assert page.status_code == 200, page.text
    jwt_value = re.search(r'name="JWT" value="([^"]+)"', page.text).group(1)  # type: ignore[union-attr]
    assert httpx.post(f"{platform.url}/deep-link-return", data={"JWT": jwt_value}).is_success
    [item] = platform.deep_link_items
    assert item["title"] == "Step response of the box"
    assert item["custom"] == {"thermolab_target": f"assignment:{assignment}"}
    return ivo, assignment, item


def test_a_linked_assignments_mark_reaches_the_lms_and_a_re_hand_in_replaces_it(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    ivo, assignment, item = _deep_link_an_assignment(lab, app_client, platform)

    # The learner launches the link: signed in, in the course, on the assignment's page.
    platform.expect(
        "lea", PendingLaunch(Person("sub-lea", "Lea", [LEARNER], "lea"), custom=item["custom"])
    )
    lea = app_client(base_url=TOOL)
    launched = _launch(lea, platform, "lea")
    assert launched.status_code == 303, launched.text
    assert launched.headers["location"] == f"/#/assignments/{assignment}"
    assert lea.get(f"/api/assignments/{assignment}").status_code == 200
    with lab.db.read() as session:
        roles = session.execute(
            select(User.username, CourseMember.role).join(
                CourseMember, CourseMember.user_id == User.id
            )
        ).all()
    assert ("lea", "student") in roles

    # A real twin run, handed in and marked: the mark reaches the gradebook.
    run_id = _run(lab, _principal(lab, "lea"))
    url = f"/api/assignments/{assignment}/submissions"
    good = lea.post(url, json={"runId": run_id, "K": 0.1401, "tau": 250.0, "theta": 0.0})
    assert good.status_code == 201, good.text
    assert good.json()["mark"] == 10.0
    score = _until(lambda: platform.gradebook.get((ITEM, "sub-lea")), lab, "first mark")
    assert (score["scoreGiven"], score["scoreMaximum"]) == (10.0, 10.0)
    assert score["gradingProgress"] == "FullyGraded"

    # A re-hand-in with a worse answer; the gradebook is busy once: retried, then replaced.
    platform.fail_scores = 1
    worse = lea.post(url, json={"runId": run_id, "K": 0.2, "tau": 250.0, "theta": 0.0})
    assert worse.status_code == 201, worse.text
    mark = worse.json()["mark"]
    assert mark == pytest.approx(10 * 4 / 6, abs=0.05)

    def failed_once() -> list[dict[str, Any]]:
        listed = ivo.get("/api/lti/grades").json()
        return [g for g in listed if g["lastError"] and "503" in g["lastError"]]

    [shown] = _until(failed_once, lab, "the failure shown to the teacher")
    assert (shown["status"], shown["scoreGiven"], shown["sub"]) == ("pending", mark, "sub-lea")
    assert platform.gradebook[(ITEM, "sub-lea")]["scoreGiven"] == 10.0  # not yet replaced
    lab.clock.advance(31)  # type: ignore[attr-defined]  # past the first back-off
    _until(lambda: platform.gradebook[(ITEM, "sub-lea")]["scoreGiven"] == mark, lab, "the new mark")
    statuses = [g["status"] for g in ivo.get("/api/lti/grades").json()]
    assert statuses == ["sent", "sent"]


def test_a_hand_in_without_a_mark_or_without_an_lms_link_posts_nothing(
    lab: Lab, app_client: Client, platform: Platform, registered: int
) -> None:
    ivo, assignment, _ = _deep_link_an_assignment(lab, app_client, platform)
    with lab.db.read() as session:
        course = session.scalars(select(Course.name).where(Course.name.startswith("lti-"))).one()
    # Bo is in the course but never came through the LMS: his mark stays in the lab.
    lab.users.add("bo", PASSWORD, "student")
    lab.courses.import_class_list(course, b"username,display_name\nbo,Bo\n")
    bo = _principal(lab, "bo")
    run_id = _run(lab, bo)
    stored = lab.assignments.hand_in(
        assignment, bo, run_id, _answers(K=0.1401, tau=250.0, theta=0.0)
    )
    assert stored.mark == 10.0
    # Lea came through the LMS but her hand-in is left for review (SRM on a short run).
    body = _assignment(methods=["srm"], settings={})
    srm = ivo.post(f"/api/courses/{course}/assignments", json=body).json()
    platform.expect(
        "lea",
        PendingLaunch(
            Person("sub-lea", "Lea", [LEARNER], "lea"),
            custom={"thermolab_target": f"assignment:{srm['id']}"},
        ),
    )
    lea = app_client(base_url=TOOL)
    assert _launch(lea, platform, "lea").status_code == 303
    short = _run(lab, _principal(lab, "lea"), samples=600)
    review = lea.post(
        f"/api/assignments/{srm['id']}/submissions",
        json={"runId": short, "K": 0.14, "tau": 250.0, "theta": 0.0},
    ).json()
    assert (review["state"], review["mark"]) == ("review", None)
    lab.lti.grades.deliver_due()
    assert lab.lti.grades.list() == []
    assert platform.gradebook == {}


def _answers(**values: float) -> Any:
    from thermolab.lab.assignments import Answers

    return Answers(**values)
