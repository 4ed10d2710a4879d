"""The rig page comes back by itself when the lab server restarts under it."""

from __future__ import annotations

from typing import Any

import pytest

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ROLE = "[data-testid=access-role]"


def test_the_page_reconnects_after_a_server_restart(browser: Any, own_lab: Any) -> None:
    context = browser.new_context(viewport={"width": 1000, "height": 800})
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        page.goto(f"{own_lab.url}/#/rig/twin")
        page.fill("#login-username", "sam")
        page.fill("#login-password", own_lab.password("sam"))
        page.click("form button[type=submit]")
        page.wait_for_selector(f"{ROLE}[data-role=watcher]")
        page.click("button[data-action=ask]")
        page.wait_for_selector(f"{ROLE}[data-role=controller]")
        # Live: the rig, now powered, sends its idle readings over the socket.
        page.wait_for_function(
            "() => document.querySelector('[data-readout=y]').textContent !== '–'"
        )
        page.evaluate("() => { window.__sameDocument = true; }")

        own_lab.stop()
        # The page says the lab cannot be reached (and locks the controls: test_turn_state.py).
        page.wait_for_selector("#conn:text('cannot be reached')", timeout=20_000)
        own_lab.start()
        own_lab.wait_until_up()
        # Back by itself (backoff at most 15 s), in the same document, logged in
        # still (sessions live in the database); a restart ends every turn, so
        # the student is watching again and may ask anew.
        page.wait_for_selector("#conn:text('Connected again')", timeout=30_000)
        assert page.evaluate("() => window.__sameDocument") is True
        page.wait_for_selector(f"{ROLE}[data-role=watcher]", timeout=10_000)
        page.click("button[data-action=ask]")
        page.wait_for_selector(f"{ROLE}[data-role=controller]")
        page.evaluate("() => { document.querySelector('[data-readout=y]').textContent = '–'; }")
        page.wait_for_function(
            "() => document.querySelector('[data-readout=y]').textContent !== '–'"
        )
        assert errors == []
    finally:
        context.close()
