"""LTI 1.3 in the real browser: registration, launches as learner and instructor, deep linking.

A test platform (``tests/lab/lti_platform.py``: its own RSA keys, JWKS over
HTTP, signed id_tokens) runs on another port of 127.0.0.1; Chromium goes
through every redirect and auto-posted form of the flow, from the LMS's page
to the lab's, inside the LMS's iframe too. The registration, a roster sync
and a grade retry are in the audit log afterwards.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from .axe import serious_violations
from .conftest import audited

pytestmark = pytest.mark.browser


def _platform_module() -> ModuleType:
    # The platform lives beside the lab tests (which use it over the API).
    path = Path(__file__).resolve().parents[1] / "lab" / "lti_platform.py"
    spec = importlib.util.spec_from_file_location("lti_test_platform", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


lti = _platform_module()


@pytest.fixture
def platform(lab: Any) -> Iterator[Any]:
    # On "localhost": another site than the lab's 127.0.0.1, so the LMS's iframe is a
    # third-party context and its posts to the lab are cross-site, as in real life.
    found = lti.Platform(lti.http_jwks(f"{lab.url}/api/lti/jwks"), host="localhost").start()
    found.tool_url = lab.url
    try:
        yield found
    finally:
        found.stop()


@pytest.fixture
def registered(logged_in: Any, lab: Any, platform: Any) -> Any:
    """The platform registered by a teacher through the LMS page, in Portuguese."""
    context = logged_in("tess", locale="pt-BR", bypass_csp=True)  # axe is injected
    try:
        page = context.new_page()
        page.goto(f"{lab.url}/#/lti")
        page.wait_for_selector("#lti-form")
        assert page.inner_text("h1") == "Ambiente virtual de aprendizagem (LTI)"
        # The tool's URLs arrive after the form is drawn (a race under load).
        page.wait_for_function(
            "url => document.querySelector('#lti-tool').textContent.includes(url)", arg=lab.url
        )
        assert page.inner_text("#lti-tool").count(lab.url) == 3
        body = platform.registration()
        for name in ("issuer", "clientId", "authLoginUrl", "tokenUrl", "jwksUrl"):
            page.fill(f"#lti-{name}", body[name])
        page.fill("#lti-deploymentIds", platform.deployment_id)
        page.click("#lti-form button[type=submit]")
        page.wait_for_selector(f'li[data-platform="{platform.url}"]')
        assert serious_violations(page) == []
        added = ("lti.platform_added", f"{body['issuer']} {body['clientId']}")
        assert added in audited(page, "tess")
    finally:
        context.close()
    return platform


@pytest.mark.parametrize(("role", "expected"), [("learner", "student"), ("instructor", "teacher")])
def test_a_launch_from_the_lms_signs_in_and_opens_the_rig(
    browser: Any, lab: Any, registered: Any, role: str, expected: str
) -> None:
    roles = [lti.LEARNER if role == "learner" else lti.INSTRUCTOR]
    hint = f"h-{role}"
    registered.expect(
        hint,
        lti.PendingLaunch(
            lti.Person(f"sub-{role}", f"Pat {role}", roles, f"pat.{role}"),
            custom={"thermolab_target": "rig:twin"},
        ),
    )
    context = browser.new_context(locale="en-GB")
    try:
        page = context.new_page()
        page.goto(f"{registered.url}/start/{hint}")
        page.wait_for_url(f"{lab.url}/#/rig/twin")
        page.wait_for_selector("#who:not([hidden])")
        assert f"pat.{role}" in page.inner_text("#who-name")
        assert expected in page.inner_text("#who-name")
        assert (page.locator("#nav-lti").is_visible()) == (expected == "teacher")
    finally:
        context.close()


def test_a_launch_inside_the_lms_iframe(browser: Any, lab: Any, registered: Any) -> None:
    registered.expect(
        "h-frame",
        lti.PendingLaunch(
            lti.Person("sub-frame", "Fia", [lti.LEARNER], "fia.frame"),
            custom={"thermolab_target": "guide:twin/theory"},
        ),
    )
    context = browser.new_context(locale="en-GB")
    try:
        page = context.new_page()
        page.goto(f"{registered.url}/course/h-frame")
        frame = page.frame_locator("#tool")
        frame.locator("#who:not([hidden])").wait_for()
        assert "fia.frame" in frame.locator("#who-name").inner_text()
        # The guide opened at the linked section, beside the rig page.
        frame.locator(".guide-drawer:not([hidden])").wait_for()
    finally:
        context.close()


def test_a_refused_launch_shows_a_translated_page(browser: Any, lab: Any, registered: Any) -> None:
    registered.expect(
        "h-late",
        lti.PendingLaunch(lti.Person("sub-late", "Léo", [lti.LEARNER]), spoil={"exp": -3600}),
    )
    context = browser.new_context(locale="pt-BR")
    try:
        page = context.new_page()
        page.goto(f"{registered.url}/start/h-late")
        page.wait_for_selector("#lti-error")
        assert page.inner_text("#lti-code") == "lti_invalid_token"
        assert "AVA" in page.inner_text("#lti-error")
    finally:
        context.close()


def test_deep_linking_round_trip_in_the_browser(browser: Any, lab: Any, registered: Any) -> None:
    registered.expect(
        "h-dl",
        lti.PendingLaunch(
            lti.Person("sub-dl", "Ivo", [lti.INSTRUCTOR], "ivo.dl"),
            message_type="LtiDeepLinkingRequest",
        ),
    )
    context = browser.new_context(locale="en-GB")
    try:
        page = context.new_page()
        page.goto(f"{registered.url}/start/h-dl")
        page.wait_for_selector("#deeplink-items input")
        # (No axe here: its injected script would need the CSP bypassed, and this test
        # checks that the answer page's own policy lets its form reach the LMS.)
        page.check('input[value="rig:twin"]')
        page.check('input[value="guide:twin/theory"]')
        page.click("#deeplink-form button[type=submit]")
        page.wait_for_selector("#linked")  # the platform's page: the signed answer arrived
    finally:
        context.close()
    targets = [i["custom"]["thermolab_target"] for i in registered.deep_link_items]
    assert targets == ["rig:twin", "guide:twin/theory"]


def test_a_teacher_sees_a_mark_the_lms_refused_and_retries_it(
    logged_in: Any, lab: Any, registered: Any
) -> None:
    from sqlalchemy import select

    from thermolab.lab.clock import SystemClock
    from thermolab.lab.db import Database
    from thermolab.lab.db.lti_models import LtiPlatform
    from thermolab.lab.lti.grades import GradeOutbox

    # "An assignment was marked": the mark is queued in the lab's database, and the
    # server's own sweep posts it to the platform, whose gradebook is busy for now.
    registered.fail_scores = 1000
    db = Database(f"sqlite:///{lab.data_dir / 'thermolab.sqlite3'}")
    try:
        with db.read() as session:
            platform_id = session.scalars(
                select(LtiPlatform.id).where(LtiPlatform.issuer == registered.url)
            ).one()
        outbox = GradeOutbox(db, SystemClock(), client=None)  # type: ignore[arg-type]
        outbox.queue_grade(
            platform_id=platform_id,
            lineitem_url=f"{registered.url}/lineitems/7",
            sub="sub-grade",
            score_given=6.5,
            score_maximum=10,
        )
    finally:
        db.close()
    context = logged_in("tess", locale="en-GB")
    try:
        page = context.new_page()
        page.goto(f"{lab.url}/#/lti")
        row = page.locator('tr[data-grade="pending"]', has_text="sub-grade")

        def reload() -> None:
            # The outbox's rows come after the page (a request of their own): a count
            # read at once after a reload saw none, and the loops below ran their whole
            # length before a read happened to fall after the rows (38 s, up to 155 s).
            page.wait_for_timeout(500)
            page.reload()
            page.wait_for_selector("#lti-grades tr", state="attached")

        page.wait_for_selector("#lti-grades tr", state="attached")
        for _ in range(60):  # the sweep tries within seconds; the page shows it on reload
            if row.count() and "HTTP 503" in row.inner_text():
                break
            reload()
        assert "HTTP 503" in row.inner_text()
        assert "6.5 / 10" in row.inner_text()
        registered.fail_scores = 0
        row.get_by_role("button").click()
        sent = page.locator('tr[data-grade="sent"]', has_text="sub-grade")
        started = time.monotonic()
        # Posted by the server's outbox thread, woken by the retry or by the next sweeps
        # (deliveries are at most every 5 s, and a token refused a moment ago is asked
        # for again only after its cool-down): allow two minutes.
        for _ in range(240):
            if sent.count():
                break
            reload()
        print(f"the retried mark was sent after {time.monotonic() - started:.1f} s")
        assert sent.count() == 1
        assert "grade.retry" in {action for action, _ in audited(page, "tess")}
    finally:
        context.close()
    assert registered.gradebook[("/lineitems/7", "sub-grade")]["scoreGiven"] == 6.5


def test_a_teacher_synchronises_the_roster_from_the_lms(
    browser: Any, logged_in: Any, lab: Any, registered: Any
) -> None:
    from sqlalchemy import select

    from thermolab.lab.db import Database
    from thermolab.lab.db.lti_models import LtiContext, LtiPlatform
    from thermolab.lab.db.models import Course

    registered.expect("h-ro", lti.PendingLaunch(lti.Person("sub-ro", "Rosa", [lti.INSTRUCTOR])))
    launcher = browser.new_context()
    try:
        page = launcher.new_page()
        page.goto(f"{registered.url}/start/h-ro")
        page.wait_for_selector("#who:not([hidden])")
    finally:
        launcher.close()
    db = Database(f"sqlite:///{lab.data_dir / 'thermolab.sqlite3'}")
    try:
        with db.read() as session:
            course = session.scalars(
                select(Course.name)
                .join(LtiContext, LtiContext.course_id == Course.id)
                .join(LtiPlatform, LtiPlatform.id == LtiContext.platform_id)
                .where(LtiPlatform.issuer == registered.url)
            ).one()
    finally:
        db.close()
    registered.roster = [
        lti.Person("sub-ro", "Rosa", [lti.INSTRUCTOR]),
        lti.Person("sub-r1", "Rui", [lti.LEARNER], "rui.roster"),
        lti.Person("sub-r2", "Rita", [lti.LEARNER], "rita.roster"),
    ]
    context = logged_in("tess", locale="pt-BR")
    try:
        page = context.new_page()
        page.goto(f"{lab.url}/#/lti")
        page.fill("#lti-course", course)
        page.click("#lti-sync")
        page.wait_for_selector("#lti-sync-report:has-text('adicionados: 2')")
        assert "removidos: 0" in page.inner_text("#lti-sync-report")
        registered.roster = [registered.roster[0], registered.roster[2]]
        page.click("#lti-sync")
        page.wait_for_selector("#lti-sync-report:has-text('removidos: 1')")
        assert "adicionados: 0" in page.inner_text("#lti-sync-report")
        assert ("course.lms_roster", course) in audited(page, "tess")
    finally:
        context.close()


def _lms_course(lab: Any, issuer: str) -> str:
    from sqlalchemy import select

    from thermolab.lab.db import Database
    from thermolab.lab.db.lti_models import LtiContext, LtiPlatform
    from thermolab.lab.db.models import Course

    db = Database(f"sqlite:///{lab.data_dir / 'thermolab.sqlite3'}")
    try:
        with db.read() as session:
            return str(
                session.scalars(
                    select(Course.name)
                    .join(LtiContext, LtiContext.course_id == Course.id)
                    .join(LtiPlatform, LtiPlatform.id == LtiContext.platform_id)
                    .where(LtiPlatform.issuer == issuer)
                ).one()
            )
    finally:
        db.close()


# In the page: the lab's own API, same origin, with the page's session.
_FETCH = """async ([method, url, body]) => {
  const answer = await fetch(url, {method, headers: {"Content-Type": "application/json"},
                                   body: body === null ? undefined : JSON.stringify(body)});
  return [answer.status, await answer.json()];
}"""


def test_a_learner_launches_a_linked_assignment_and_the_mark_reaches_the_lms(
    browser: Any, lab: Any, registered: Any
) -> None:
    # The instructor's deep-linking launch (it makes the LMS course's lab course), an
    # assignment set in that course, chosen in the picker.
    registered.expect(
        "h-as",
        lti.PendingLaunch(
            lti.Person("sub-as", "Inês", [lti.INSTRUCTOR], "ines.assign"),
            message_type="LtiDeepLinkingRequest",
        ),
    )
    teacher = browser.new_context(locale="en-GB")
    try:
        page = teacher.new_page()
        page.goto(f"{registered.url}/start/h-as")
        page.wait_for_selector("#deeplink-items input")
        course = _lms_course(lab, registered.url)
        body = {
            "title": "Degrau pela LMS",
            "instructions": "Step 0 to 10 V; give Ks, Ts and θ.",
            "rig": "twin",
            "methods": ["lsm"],
            "settings": {},
            "deadline": "2099-12-31T23:00:00+00:00",
            "tolerance": {"K": 0.05, "tau": 0.05, "theta": 5.0},
        }
        status, made = page.evaluate(_FETCH, ["POST", f"/api/courses/{course}/assignments", body])
        assert status == 201, made
        target = f"assignment:{made['id']}"
        page.reload()
        page.wait_for_selector(f'input[value="{target}"]')
        assert "Assignment: Degrau pela LMS" in page.inner_text("#deeplink-items")
        page.check(f'input[value="{target}"]')
        page.click("#deeplink-form button[type=submit]")
        page.wait_for_selector("#linked")
    finally:
        teacher.close()
    [item] = registered.deep_link_items
    assert item["custom"] == {"thermolab_target": target}

    # The learner launches the link: signed in, on the assignment's page, able to hand in.
    registered.expect(
        "h-al",
        lti.PendingLaunch(
            lti.Person("sub-al", "Alice", [lti.LEARNER], "alice.assign"), custom=item["custom"]
        ),
    )
    learner = browser.new_context(locale="en-GB")
    try:
        page = learner.new_page()
        page.goto(f"{registered.url}/start/h-al")
        page.wait_for_url(f"{lab.url}/#/assignments/{made['id']}")
        page.wait_for_selector("#handin-form")
        assert page.inner_text("h1") == "Degrau pela LMS"
        # A real run on the twin (through the lab's API), then the hand-in form.
        for method, url, spec in (
            ("POST", "/api/rigs/twin/control", None),
            (
                "POST",
                "/api/rigs/twin/runs",
                {"dt": 1.0, "samples": 1500, "signal": "step:0:10@5", "methods": ["lsm"]},
            ),
        ):
            status, answer = page.evaluate(_FETCH, [method, url, spec])
            assert status in (200, 201), answer
        run_id = answer["id"]
        for _ in range(120):
            status, run = page.evaluate(_FETCH, ["GET", f"/api/runs/{run_id}", None])
            if run.get("status") == "finished":
                break
            page.wait_for_timeout(500)
        assert run["status"] == "finished", run
        page.evaluate(_FETCH, ["DELETE", "/api/rigs/twin/control", None])
        page.reload()
        page.wait_for_selector(f"#handin-run option[value='{run_id}']", state="attached")
        page.select_option("#handin-run", str(run_id))
        page.fill("#handin-k", "0.1401")
        page.fill("#handin-tau", "250")
        page.fill("#handin-theta", "0")
        page.click("#handin-form button[type=submit]")
        page.wait_for_selector("[data-testid=mark]")
    finally:
        learner.close()
    # The server's outbox posts the mark to the LMS's gradebook.
    for _ in range(120):
        if ("/lineitems/1", "sub-al") in registered.gradebook:
            break
        time.sleep(0.25)
    score = registered.gradebook[("/lineitems/1", "sub-al")]
    assert (score["scoreGiven"], score["scoreMaximum"]) == (10.0, 10.0)
