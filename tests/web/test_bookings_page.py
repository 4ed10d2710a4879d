"""Bookings in the browser (#10 item 5), in English and Brazilian Portuguese, on a real server.

A teacher books a slot for a course on the calendar page (times typed in the
browser's zone); booking the same slot again is refused with the slot named.
A student of another course who held the rig loses the turn when the slot
begins and is told why, and asking again is refused with the slot's times;
a student of the course sees the slot on the rig page and takes control
inside it. The calendar is axe-clean and fits a 375-px phone.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any
from zoneinfo import ZoneInfo

import pytest

from .axe import serious_violations
from .conftest import LabServer, running_lab
from .test_turn_state import NOTICE, ROLE, catalogue, fill

pytestmark = pytest.mark.browser

CONFIG = """\
title = "ThermoLab bookings"

[[rigs]]
id = "book-en"
title = "Twin booked in English"
spec = "sim"

[[rigs]]
id = "book-ptbr"
title = "Twin booked in Portuguese"
spec = "sim"
"""
USERS = {"tess": "teacher", "ines": "student", "otto": "student"}
# Each language in its own time zone: the slot is typed, and shown, in the browser's.
LANGUAGES = {
    "en": ("en-GB", "book-en", "Europe/London"),
    "pt-BR": ("pt-BR", "book-ptbr", "America/Sao_Paulo"),
}


@pytest.fixture(scope="module")
def booking_lab(tmp_path_factory: pytest.TempPathFactory, browser: Any) -> Iterator[LabServer]:
    with running_lab(tmp_path_factory.mktemp("bookings"), USERS, config=CONFIG) as server:
        # ines is in "inside", otto in "outside" (the command line, on the lab's database).
        for course, student in (("inside", "ines"), ("outside", "otto")):
            _cli(
                server,
                "course",
                "create",
                course,
                "--title",
                f"Course {course}",
                "--teacher",
                "tess",
            )
            roster = server.data_dir / f"{course}.csv"
            roster.write_text(f"username,display_name\n{student},{student.title()}\n")
            _cli(server, "course", "import", course, str(roster))
        yield server


def _cli(lab: LabServer, *args: str) -> None:
    command = [sys.executable, "-m", "thermolab", "--data-dir", str(lab.data_dir), *args]
    done = subprocess.run(command, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stdout + done.stderr


def _page(browser: Any, lab: LabServer, user: str, locale: str, path: str, **options: Any) -> Any:
    context = browser.new_context(locale=locale, bypass_csp=True, **options)  # axe is injected
    page = context.new_page()
    page.goto(f"{lab.url}/#{path}")
    page.fill("#login-username", user)
    page.fill("#login-password", lab.password(user))
    page.click("form button[type=submit]")
    page.wait_for_selector("#nav:not([hidden])")
    return page


@pytest.mark.parametrize("language", list(LANGUAGES))
def test_a_teacher_books_a_slot_its_course_takes_the_rig_and_an_outsider_is_refused(
    language: str, browser: Any, booking_lab: LabServer, artifacts: Path
) -> None:
    locale, rig, zone = LANGUAGES[language]
    words = catalogue(language)
    lab = booking_lab
    otto = _page(browser, lab, "otto", locale, f"/rig/{rig}", timezone_id=zone)
    tess = _page(browser, lab, "tess", locale, "/bookings", timezone_id=zone)
    ines = None
    try:
        # Before the slot, otto (of the other course) controls the rig.
        otto.wait_for_selector(f"{ROLE}[data-role=watcher]")
        otto.click("button[data-action=ask]")
        otto.wait_for_selector(f"{ROLE}[data-role=controller]")
        otto.wait_for_selector("[data-testid=chance-now]:not(:empty)")
        assert otto.inner_text("[data-testid=chance-now]") == words["chance.free"]

        # The teacher books the rig for "inside", from this minute for an hour (browser time).
        tess.wait_for_selector(f"#booking-rig-{rig}")
        assert tess.inner_text("h1") == words["calendar.title"]
        start = datetime.now(ZoneInfo(zone)).replace(second=0, microsecond=0)
        end = start + timedelta(hours=1)
        tess.select_option("#booking-course", "inside")
        tess.check(f"#booking-rig-{rig}")
        tess.fill("#booking-date", start.strftime("%Y-%m-%d"))
        tess.fill("#booking-end-date", end.strftime("%Y-%m-%d"))  # past midnight: the next day
        tess.fill("#booking-start", start.strftime("%H:%M"))
        tess.fill("#booking-end", end.strftime("%H:%M"))
        tess.click("#booking-submit")
        # This language's rig: the module's other language books the same course.
        slot = tess.locator("[data-testid=slot]", has_text="Course inside").filter(has_text=rig)
        slot.first.wait_for()
        assert rig in slot.first.inner_text()
        assert serious_violations(tess) == []
        tess.screenshot(path=str(artifacts / f"calendar-{language}.png"), full_page=True)

        # The same slot again clashes; the message names the slot in the way.
        tess.check(f"#booking-rig-{rig}")
        tess.click("#booking-submit")
        tess.wait_for_selector("#booking-error:not(:empty)")
        clash = tess.inner_text("#booking-error")
        assert clash.startswith(words["error.booking_clash"].split("{")[0]), clash
        assert "inside" in clash
        assert rig in clash

        # The slot has begun: otto's turn ends (the sweep, within a second or two), and he is told.
        otto.wait_for_selector(f"{ROLE}[data-role=watcher]", timeout=15_000)
        otto.wait_for_function(
            "(m) => document.querySelector('[data-testid=turn-notice]').textContent.includes(m)",
            arg=words["turn.endedBooked"],
        )
        assert otto.is_visible(NOTICE)
        # Asking again is refused, with the slot's times.
        otto.click("button[data-action=ask]")
        otto.wait_for_selector("[data-testid=rig-error]:not(:empty)")
        refusal = otto.inner_text("[data-testid=rig-error]")
        assert refusal.startswith(words["error.rig_booked"].split("{")[0]), refusal
        otto.wait_for_function(
            "(m) => document.querySelector('[data-testid=chance-now]').textContent.startsWith(m)",
            arg=words["chance.otherNow"].split("{")[0],
            timeout=40_000,
        )

        # ines (of the course) sees her course's slot on the rig page and takes control.
        ines = _page(browser, lab, "ines", locale, f"/rig/{rig}", timezone_id=zone)
        ines.wait_for_selector(f"{ROLE}[data-role=watcher]")
        own = fill(words["chance.ownNow"], course="Course inside").split("{")[0]
        ines.wait_for_function(
            "(m) => document.querySelector('[data-testid=chance-now]').textContent.startsWith(m)",
            arg=own,
        )
        ines.click("button[data-action=ask]")
        ines.wait_for_selector(f"{ROLE}[data-role=controller]")

        # A student reads the calendar on a phone: her course named, axe-clean, no sideways scroll.
        ines.set_viewport_size({"width": 375, "height": 812})
        ines.goto(f"{lab.url}/#/bookings")
        ines.locator("[data-testid=slot]", has_text="Course inside").first.wait_for()
        assert ines.locator("#booking-form").count() == 0  # students do not book
        assert ines.evaluate("() => document.documentElement.scrollWidth") <= 375
        assert serious_violations(ines) == []
        # Otto sees the same slot only as reserved, without the course's name.
        otto.goto(f"{lab.url}/#/bookings")
        reserved = otto.locator("[data-testid=slot]", has_text=words["calendar.reserved"])
        reserved.first.wait_for()
        assert "inside" not in reserved.first.inner_text()

        # The teacher's calendar, with its form, fits a phone too.
        tess.set_viewport_size({"width": 375, "height": 812})
        assert tess.evaluate("() => document.documentElement.scrollWidth") <= 375
        # Cancel the slot, so the other language's test starts from a free calendar.
        slot.first.locator("button", has_text=words["calendar.cancel"]).click()
        tess.wait_for_selector("[data-testid=slot]", state="detached")
    finally:
        for page in (otto, tess, ines):
            if page is not None:
                page.context.close()
