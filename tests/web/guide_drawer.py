"""Opening a rig page's guide drawer from a panel's "Guide" button, as a person does."""

from __future__ import annotations

from typing import Any

__all__ = ["open_panel_guide"]


def open_panel_guide(
    page: Any, panel: str = "srm-lsm", section: str = "panel-1", *, loaded: bool = True
) -> None:
    """Click ``panel``'s guide button until the drawer shows the guide's text.

    With ``loaded=False``, until the drawer shows (for a test that holds the read).

    A click that reached the button while the rig page was still drawing was
    lost now and then in full CI runs (the drawer never opened: ci2 and ci4 in
    the guide test, ci5 in the journey; never in a thousand runs alone). A person
    clicks again, and so does this; each click's fate is in the page diary.
    """
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    opener = page.locator(f"#panel-{panel} button[data-guide={section}]")
    shown = page.locator("[data-testid=guide-text] > *" if loaded else "[data-testid=guide]")
    text = shown.first
    for _ in range(4):
        opener.click()
        try:
            text.wait_for(timeout=15_000)
            return
        except PlaywrightTimeout:
            continue
    opener.click()
    text.wait_for()
