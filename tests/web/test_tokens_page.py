"""My account: an API token made in the browser works for a script until revoked there (#11)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx
import pytest

pytestmark = pytest.mark.browser


def test_a_token_is_made_shown_once_used_and_revoked_in_the_browser(
    logged_in: Any, lab: Any, artifacts: Path
) -> None:
    context = logged_in("erin")
    try:
        page = context.new_page()
        page.goto(f"{lab.url}/#/account")
        page.wait_for_selector("#token-name")
        page.click("form button[type=submit]")  # no name: refused before sending
        assert page.inner_text("#token-error") == "Give the token a name."
        page.fill("#token-name", "course notebook")
        page.click("form button[type=submit]")
        page.wait_for_selector("#token-value")
        secret = page.input_value("#token-value")
        assert secret.startswith("tlab_")
        row = page.locator("tr[data-token]")
        row.wait_for()
        assert "course notebook" in row.inner_text()
        assert secret not in page.inner_text("table")  # the list shows its first characters
        page.screenshot(path=str(artifacts / "account-tokens.png"), full_page=True)
        auth = {"authorization": f"Bearer {secret}"}
        me = httpx.get(f"{lab.url}/api/session", headers=auth, timeout=10)
        assert me.json()["username"] == "erin"
        page.click("tr[data-token] button")
        page.wait_for_selector("tr[data-token]", state="detached")
        assert httpx.get(f"{lab.url}/api/session", headers=auth, timeout=10).status_code == 401
        # The secret is not shown again on a new visit.
        page.reload()
        page.wait_for_selector("#token-name")
        assert page.locator("#token-value").count() == 0
    finally:
        context.close()
