"""Time and state a student can see (WCAG 2.2.1, 4.1.3), in a real browser against real servers.

Warnings at 60 s and 20 s before a turn ends, with "extend" only while nobody
waits; a visible message when a teacher ends the turn; while the server is
down (killed) the page says so and locks the controls; after the restart it
says the run was interrupted and the turn ended.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .conftest import LabServer, running_lab

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ROLE = "[data-testid=access-role]"
WARNING = "[data-testid=time-warning]"
NOTICE = "[data-testid=turn-notice]"
NOTICE_SAYS = "(m) => document.querySelector('[data-testid=turn-notice]').textContent.includes(m)"
LOCK = "[data-testid=lock-notice]"
EXTEND = "button[data-action=extend]"
MESSAGES = Path(__file__).parents[2] / "src/thermolab/web/static/js/messages"

# Short turns, so that the last minute comes within seconds of real time (40 s: the
# 20-s warning comes after the second student has queued, even on a loaded machine).
CONFIG = """\
title = "ThermoLab turns"

[[rigs]]
id = "short"
title = "Seventy-second turns"
spec = "sim"
control_time_limit = 70.0

[[rigs]]
id = "brief"
title = "Forty-second turns"
spec = "sim"
control_time_limit = 40.0

[[rigs]]
id = "kick"
title = "A rig the teacher acts on"
spec = "sim"
"""
USERS = {"ana": "student", "ben": "student", "tess": "teacher"}


def catalogue(language: str) -> dict[str, Any]:
    text = (MESSAGES / f"{language}.js").read_text(encoding="utf-8")
    body = text[text.index("= {") + 2 : text.rindex("}") + 1]
    messages: dict[str, Any] = json.loads(body)
    return messages


def fill(message: str, **params: str) -> str:
    for name, value in params.items():
        message = message.replace("{" + name + "}", value)
    return message


@pytest.fixture(scope="module")
def turns_lab(tmp_path_factory: pytest.TempPathFactory, browser: Any) -> Iterator[LabServer]:
    with running_lab(tmp_path_factory.mktemp("turns"), USERS, config=CONFIG) as server:
        yield server


def open_rig(browser: Any, lab: LabServer, user: str, rig: str, locale: str) -> tuple[Any, Any]:
    context = browser.new_context(locale=locale, viewport={"width": 1000, "height": 900})
    page = context.new_page()
    page.goto(f"{lab.url}/#/rig/{rig}")
    page.fill("#login-username", user)
    page.fill("#login-password", lab.password(user))
    page.click("form button[type=submit]")
    page.wait_for_selector(f"{ROLE}[data-role=watcher]")
    # Everything said in the polite region, in order (it is cleared between messages).
    page.evaluate(
        """() => {
          window.__said = [];
          const region = document.getElementById('announce-polite');
          new MutationObserver(() => {
            if (region.textContent) window.__said.push(region.textContent);
          }).observe(region, { childList: true, characterData: true, subtree: true });
        }"""
    )
    return context, page


def test_warnings_before_the_end_and_extend_while_nobody_waits(
    browser: Any, turns_lab: LabServer
) -> None:
    pt = catalogue("pt-BR")
    context, page = open_rig(browser, turns_lab, "ana", "short", "pt-BR")
    try:
        page.click("button[data-action=ask]")
        page.wait_for_selector(f"{ROLE}[data-role=controller]")
        assert page.is_hidden(WARNING)  # 70 s left: no warning yet
        # The last minute: said politely, shown beside the countdown, "extend" offered.
        page.wait_for_selector(f"{WARNING}:visible", timeout=20_000)
        page.wait_for_selector(f"{EXTEND}:visible", timeout=5_000)
        # The polite region is cleared, then given the sentence a moment later (so a
        # screen reader says it again): the warning may be on screen before it is said.
        expected = fill(pt["access.timeWarning"], time="1 minuto")
        page.wait_for_function("(m) => window.__said.includes(m)", arg=expected, timeout=30_000)
        warning = page.text_content(WARNING) or ""
        assert "Ninguém está esperando" in warning
        # On a phone the warning and EXTEND take the facts' place in the access card, so
        # the chart, START/END and the panel's instruction stay on the first screen.
        page.set_viewport_size({"width": 375, "height": 812})
        page.evaluate("() => window.scrollTo(0, 0)")
        bottoms = """() => ['[data-testid=time-warning]', 'button[data-action=extend]',
                      '[data-panel-view]:not([hidden]) .panel-intro',
                      '[data-panel-view]:not([hidden]) button[data-action=end]']
                .map((s) => document.querySelector(s).getBoundingClientRect().bottom)"""
        from playwright.sync_api import TimeoutError as PlaywrightTimeout

        # The page lays itself out again after the resize (on a loaded machine a
        # measure taken at once saw the wide layout's 826 px): wait for the phone's.
        with contextlib.suppress(PlaywrightTimeout):
            page.wait_for_function(f"() => Math.max(...({bottoms})()) <= 812", timeout=15_000)
        first_screen = page.evaluate(bottoms)
        assert max(first_screen) <= 812, first_screen
        page.set_viewport_size({"width": 1000, "height": 900})
        page.click(EXTEND)
        page.wait_for_selector(WARNING, state="hidden")
        page.wait_for_function(
            "() => window.__said.some((m) => m.startsWith('Sua vez foi prolongada'))"
        )
        left = page.evaluate(
            "async () => (await (await fetch('/api/rigs/short')).json()).access.timeLeft"
        )
        assert 150 < left <= 180
        assert page.is_visible(f"{ROLE}[data-role=controller]")
    finally:
        context.close()


def test_the_twenty_second_warning_and_no_extend_when_someone_waits(
    browser: Any, turns_lab: LabServer
) -> None:
    en = catalogue("en")
    context, page = open_rig(browser, turns_lab, "ana", "brief", "en-US")
    other, ben = open_rig(browser, turns_lab, "ben", "brief", "en-US")
    try:
        page.click("button[data-action=ask]")
        page.wait_for_selector(f"{ROLE}[data-role=controller]")
        # 40 s left: already in the last minute, nobody waits: extend is offered.
        page.wait_for_selector(f"{WARNING}:visible")
        page.wait_for_selector(f"{EXTEND}:visible")
        ben.click("button[data-action=ask]")
        ben.wait_for_selector(f"{ROLE}[data-role=queued]")
        # Someone waits now: no extension (the server's canExtend, sent live).
        page.wait_for_selector(EXTEND, state="hidden", timeout=5_000)
        assert "Nobody is waiting" not in (page.text_content(WARNING) or "")
        page.wait_for_function(
            "(m) => window.__said.includes(m)",
            arg=fill(en["access.timeWarning"], time="20 seconds"),
            timeout=30_000,
        )
        # The turn ends at its limit and the page says why, and ben gets the rig.
        page.wait_for_function(
            "() => document.querySelector('[data-testid=access-role]').dataset.role === 'watcher'",
            timeout=40_000,  # 20 s left at the warning, plus the sweep on a loaded machine
        )
        page.wait_for_selector(f"{NOTICE}:text('{en['turn.endedTime']}')")
        ben.wait_for_selector(f"{ROLE}[data-role=controller]")
    finally:
        context.close()
        other.close()


def test_a_student_sees_that_a_teacher_ended_the_turn(browser: Any, turns_lab: LabServer) -> None:
    pt = catalogue("pt-BR")
    context, page = open_rig(browser, turns_lab, "ana", "kick", "pt-BR")
    teacher, tess = open_rig(browser, turns_lab, "tess", "kick", "en-US")
    try:
        page.click("button[data-action=ask]")
        page.wait_for_selector(f"{ROLE}[data-role=controller]")
        answer = tess.evaluate(
            """async () => (await fetch('/api/rigs/kick/control/kick', {
                 method: 'POST', headers: {'Content-Type': 'application/json'}, body: '{}'
               })).status"""
        )
        assert answer == 200
        page.wait_for_selector(f"{ROLE}[data-role=watcher]")
        notice = page.locator(NOTICE)
        notice.wait_for(state="visible")
        assert notice.text_content() == fill(pt["turn.endedKicked"], by="tess")
        assert notice.get_attribute("role") == "status"
    finally:
        context.close()
        teacher.close()


def test_a_server_down_locks_the_page_and_the_restart_is_explained(
    browser: Any, tmp_path: Path
) -> None:
    en = catalogue("en")
    with running_lab(tmp_path, {"sam": "student"}, config=CONFIG) as server:
        context, page = open_rig(browser, server, "sam", "kick", "en-US")
        try:
            page.click("button[data-action=ask]")
            page.wait_for_selector(f"{ROLE}[data-role=controller]")
            run = page.evaluate(
                """async () => (await (await fetch('/api/rigs/kick/runs', {
                     method: 'POST', headers: {'Content-Type': 'application/json'},
                     body: JSON.stringify({dt: 1, samples: 20000, setpoint: 2,
                                           methods: ['lsm']})
                   })).json()).id"""
            )
            assert isinstance(run, int)
            page.wait_for_selector("[data-testid=run-progress]:visible", timeout=10_000)

            server.kill()
            # Unreachable: said on the page, the role and countdown gone, the panels locked.
            page.wait_for_selector(f"#conn:text('{en['turn.connLost']}')", timeout=20_000)
            page.wait_for_selector(f"{ROLE}[data-role=unknown]")
            assert page.text_content(ROLE) == en["turn.unreachable"]
            assert page.text_content("[data-field=timeLeft]") == "–"
            assert page.is_hidden("button[data-action=release]")
            assert page.text_content(LOCK) == en["turn.locked"]
            assert page.locator("fieldset:not([disabled]) button").count() == 0

            server.start()
            server.wait_until_up()
            notice = page.locator(NOTICE)
            page.wait_for_function(
                NOTICE_SAYS,
                arg=fill(en["turn.runInterrupted"], run=str(run)),
                timeout=30_000,
            )
            page.wait_for_function(
                NOTICE_SAYS,
                arg=en["turn.endedRestart"],
            )
            assert notice.is_visible()
            page.wait_for_selector(f"{ROLE}[data-role=watcher]")
            page.wait_for_selector(f"#conn:text('{en['conn.again']}')", timeout=30_000)
        finally:
            context.close()
