"""The booking tools in the browser (issue #24, item 7), on a real server with a real SMTP server.

A teacher sets a course's weekly quota, books a weekly series (one week in the
way is listed and left out), has swapped times refused (no longer booked 23
hours over midnight) and makes a calendar feed that a calendar application
reads without a login, then revokes it. A student books a free slot for
herself within the quota, cancels nothing but her own, and asks for an e-mail
reminder, which the lab's sweep sends once to the local SMTP server
(``aiosmtpd``). One lab for the module.
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from email import message_from_string
from email.message import EmailMessage
from email.policy import default
from typing import Any
from zoneinfo import ZoneInfo

import httpx
import pytest
from aiosmtpd.controller import Controller
from icalendar import Calendar

from .axe import serious_violations
from .conftest import LabServer, running_lab
from .test_turn_state import catalogue

pytestmark = pytest.mark.browser

USERS = {"tess": "teacher", "theo": "teacher", "ines": "student"}


class _Inbox:
    def __init__(self) -> None:
        self.messages: list[tuple[list[str], str]] = []

    async def handle_DATA(self, server: Any, session: Any, envelope: Any) -> str:  # noqa: N802
        self.messages.append((list(envelope.rcpt_tos), envelope.content.decode()))
        return "250 OK"


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(scope="module")
def tools_lab(
    tmp_path_factory: pytest.TempPathFactory, browser: Any
) -> Iterator[tuple[LabServer, _Inbox]]:
    inbox = _Inbox()
    port = _free_port()
    smtp = Controller(inbox, hostname="127.0.0.1", port=port)
    smtp.start()
    config = f"""\
title = "ThermoLab tools"

[smtp]
host = "127.0.0.1"
port = {port}
sender = "lab@example.org"

[[rigs]]
id = "tool-a"
title = "Twin A"
spec = "sim"

[[rigs]]
id = "tool-b"
title = "Twin B"
spec = "sim"
"""
    try:
        with running_lab(tmp_path_factory.mktemp("tools"), USERS, config=config) as server:
            for course, teacher in (("inside", "tess"), ("other", "theo")):
                _cli(
                    server,
                    "course",
                    "create",
                    course,
                    "--title",
                    f"Course {course}",
                    "--teacher",
                    teacher,
                )
            roster = server.data_dir / "inside.csv"
            roster.write_text("username,display_name\nines,Ines\n")
            _cli(server, "course", "import", "inside", str(roster))
            yield server, inbox
    finally:
        smtp.stop()


def _cli(lab: LabServer, *args: str) -> None:
    command = [sys.executable, "-m", "thermolab", "--data-dir", str(lab.data_dir), *args]
    done = subprocess.run(command, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stdout + done.stderr


def _midday_zone() -> str:
    """A zone where it is about noon now, so slots of a few hours never cross midnight."""
    hours = (12 - datetime.now(UTC).hour + 12) % 24 - 12  # -12 .. 11
    if hours == 0:
        # Chromium names "Etc/GMT+0" "UTC" (its ICU alias); at noon UTC ask for UTC itself.
        return "UTC"
    return "Etc/GMT" + ("+" if hours < 0 else "-") + str(abs(hours))  # Etc/GMT-N is UTC+N


def _page(browser: Any, lab: LabServer, user: str, zone: str) -> Any:
    context = browser.new_context(locale="en-GB", bypass_csp=True, timezone_id=zone)
    page = context.new_page()
    page.goto(f"{lab.url}/#/bookings")
    page.fill("#login-username", user)
    page.fill("#login-password", lab.password(user))
    page.click("form button[type=submit]")
    page.wait_for_selector("#nav:not([hidden])")
    return page


def test_quota_series_feed_own_booking_and_reminder(
    browser: Any, tools_lab: tuple[LabServer, _Inbox]
) -> None:
    lab, inbox = tools_lab
    words = catalogue("en")
    zone = _midday_zone()
    now = datetime.now(ZoneInfo(zone)).replace(second=0, microsecond=0)
    tess = _page(browser, lab, "tess", zone)
    theo = httpx.Client(base_url=lab.url)
    ines = None
    try:
        # Theo's course holds rig A a week tomorrow: the series' second week is in the way.
        login = {"username": "theo", "password": lab.password("theo")}
        assert theo.post("/api/session", json=login).status_code == 200
        tomorrow = now + timedelta(days=1)
        in_way = tomorrow.replace(hour=9) + timedelta(weeks=1)
        held = theo.post(
            "/api/bookings",
            json={
                "course": "other",
                "rigs": ["tool-a"],
                "startsAt": in_way.isoformat(),
                "endsAt": (in_way + timedelta(minutes=30)).isoformat(),
            },
        )
        assert held.status_code == 201, held.text

        # The quota: 120 minutes a week for "inside".
        tess.wait_for_selector("#quota-minutes[data-course=inside]")  # tess's one course
        tess.fill("#quota-minutes", "120")
        tess.click("#quota-save")
        tess.wait_for_function(
            "() => document.querySelector('#quota-status').textContent.includes('120')"
        )

        # Swapped times: refused, with the stable code's words; nothing booked.
        tess.wait_for_selector("#booking-rig-tool-a")
        tess.select_option("#booking-course", "inside")
        tess.check("#booking-rig-tool-a")
        tess.fill("#booking-date", tomorrow.strftime("%Y-%m-%d"))
        tess.fill("#booking-end-date", tomorrow.strftime("%Y-%m-%d"))
        tess.fill("#booking-start", "10:00")
        tess.fill("#booking-end", "08:00")
        tess.click("#booking-submit")
        tess.wait_for_selector("#booking-error:not(:empty)")
        assert tess.inner_text("#booking-error") == words["error.slot_ends_before_start"]

        # A weekly series for three weeks, the week in the way left out and listed.
        tess.fill("#booking-start", "09:00")
        tess.fill("#booking-end", "10:00")
        until = tomorrow + timedelta(weeks=2)
        tess.fill("#booking-repeat-until", until.strftime("%Y-%m-%d"))
        tess.check("#booking-skip-clashes")
        with tess.expect_request(lambda r: r.url.endswith("/api/booking-series")) as sent:
            tess.click("#booking-submit")
        # The weeks keep the page's wall-clock time: it sends the browser's zone.
        browser_zone = tess.evaluate("Intl.DateTimeFormat().resolvedOptions().timeZone")
        assert browser_zone == zone
        assert json.loads(sent.value.post_data or "{}")["zone"] == browser_zone
        tess.wait_for_function(
            "(p) => document.querySelector('#booking-error').textContent.startsWith(p)",
            arg=words["calendar.seriesSkipped"].split("{")[0],
        )
        tess.locator("[data-testid=slot]", has_text="Course inside").first.wait_for()
        assert serious_violations(tess) == []

        # A feed of all tess's courses, read by a calendar application without a cookie.
        tess.click("#feed-create")
        tess.wait_for_selector("#feed-url:not([hidden])")
        url = tess.input_value("#feed-url")
        feed = httpx.get(url)
        assert feed.status_code == 200
        assert feed.headers["content-type"].startswith("text/calendar")
        starts = sorted(
            e.decoded("dtstart") for e in Calendar.from_ical(feed.content).walk("VEVENT")
        )
        assert len(starts) == 2
        assert starts[1] - starts[0] == timedelta(weeks=2)
        tess.locator("[data-testid=feed] button").first.click()
        tess.wait_for_selector("[data-testid=feed]", state="detached")
        assert httpx.get(url).status_code == 404

        # Ines books for herself within the quota, and asks for a reminder 2 hours ahead.
        ines = _page(browser, lab, "ines", zone)
        ines.wait_for_selector("#own-form")
        start = now + timedelta(minutes=60)
        ines.select_option("#own-rig", "tool-b")
        ines.fill("#own-date", start.strftime("%Y-%m-%d"))
        ines.fill("#own-start", start.strftime("%H:%M"))
        ines.fill("#own-end", (start + timedelta(minutes=30)).strftime("%H:%M"))
        ines.click("#own-submit")
        ines.wait_for_function(
            "() => document.querySelector('#own-left').textContent.includes('30 of your 120')"
        )
        mine = ines.locator("[data-testid=slot]", has_text="tool-b").first
        mine.wait_for()
        assert mine.locator("button", has_text=words["calendar.cancel"]).count() == 1
        # Past the quota: refused with its words.
        ines.fill("#own-start", (start + timedelta(minutes=60)).strftime("%H:%M"))
        ines.fill("#own-end", (start + timedelta(minutes=160)).strftime("%H:%M"))
        ines.click("#own-submit")
        ines.wait_for_selector("#own-error:not(:empty)")
        assert ines.inner_text("#own-error") == words["error.booking_quota_exceeded"]

        ines.wait_for_selector("#reminder-form:not([hidden])")
        ines.fill("#reminder-email", "ines@example.org")
        ines.fill("#reminder-minutes", "120")
        ines.click("#reminder-save")
        ines.wait_for_function(
            "(m) => document.querySelector('#reminder-status').textContent.includes(m)",
            arg="ines@example.org",
        )
        assert serious_violations(ines) == []
        # The lab's sweep sends due reminders every 30 s: her own booking (in an hour) is due.
        deadline = time.monotonic() + 60
        while not inbox.messages and time.monotonic() < deadline:
            time.sleep(0.5)
        assert [to for to, _ in inbox.messages] == [["ines@example.org"]]
        mail = message_from_string(inbox.messages[0][1], policy=default)
        assert isinstance(mail, EmailMessage)
        text = mail.get_content()
        assert "Course inside" in text
        assert "tool-b" in text
        # Sent once: recorded before sending (tests/lab/test_booking_tools.py restarts the sender).
    finally:
        theo.close()
        for page in (tess, ines):
            if page is not None:
                page.context.close()
