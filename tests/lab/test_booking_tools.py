"""The booking tools (issue #24, item 7): slot times, students' own bookings within a quota,
weekly series, calendar feeds, e-mail reminders (against a real SMTP server)."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator
from datetime import UTC, date, datetime, timedelta, timezone
from email import message_from_string
from email.message import EmailMessage
from email.policy import default
from typing import Any
from zoneinfo import ZoneInfo

import pytest
from aiosmtpd.controller import Controller
from fastapi.testclient import TestClient
from hypothesis import given
from hypothesis import strategies as st
from icalendar import Calendar

from thermolab.errors import SlotReversedError, SlotTooLongError, SlotZoneError
from thermolab.lab.accounts.personal_data import forget_person
from thermolab.lab.classes.reminders import ReminderService
from thermolab.lab.classes.slot_times import MAX_LONG_SLOT_DAYS, MAX_SLOT_HOURS, check_slot
from thermolab.lab.clock import ManualClock
from thermolab.lab.config.smtp import SmtpConfig
from thermolab.lab.db.booking_tool_models import CalendarFeed, ReminderAddress
from thermolab.lab.service import Lab

from .conftest import LabFactory
from .test_bookings import course, iso, person

Clients = Callable[..., TestClient]
T0 = datetime(2026, 1, 1, tzinfo=UTC)

# -- the validator, as properties --------------------------------------------------------

_zones = st.integers(min_value=-12 * 60, max_value=14 * 60).map(
    lambda m: timezone(timedelta(minutes=m))
)
_instants = st.datetimes(
    min_value=datetime(2000, 1, 1), max_value=datetime(2100, 1, 1), timezones=_zones
)
_lengths = st.timedeltas(min_value=timedelta(seconds=-10 * 86400), max_value=timedelta(days=10))


@given(start=_instants, length=_lengths, longer=st.booleans(), zone=_zones)
def test_a_slot_is_accepted_exactly_when_it_ends_after_it_starts_within_its_longest(
    start: datetime, length: timedelta, longer: bool, zone: timezone
) -> None:
    end = (start + length).astimezone(zone)  # the end written in another zone
    longest = timedelta(days=MAX_LONG_SLOT_DAYS) if longer else timedelta(hours=MAX_SLOT_HOURS)
    if length <= timedelta(0):
        with pytest.raises(SlotReversedError):
            check_slot(start, end, longer=longer)
    elif length > longest:
        with pytest.raises(SlotTooLongError):
            check_slot(start, end, longer=longer)
    else:
        a, b = check_slot(start, end, longer=longer)
        assert (a, b) == (start, end)  # the same instants ...
        assert a.utcoffset() == b.utcoffset() == timedelta(0)  # ... in UTC
        assert timedelta(0) < b - a <= longest


@given(start=_instants, length=_lengths, which=st.sampled_from(["start", "end", "both"]))
def test_a_time_without_its_zone_is_refused_whatever_else(
    start: datetime, length: timedelta, which: str
) -> None:
    end = start + length
    naive_start = start.replace(tzinfo=None) if which in ("start", "both") else start
    naive_end = end.replace(tzinfo=None) if which in ("end", "both") else end
    with pytest.raises(SlotZoneError):
        check_slot(naive_start, naive_end, longer=True)


@given(
    day=st.dates(min_value=date(2000, 1, 1), max_value=date(2099, 12, 30)),
    first=st.times(),
    second=st.times(),
)
def test_swapped_times_of_one_day_are_refused_never_moved_past_midnight(
    day: date, first: Any, second: Any
) -> None:
    """The old page's bug: "10:00 to 08:00" became 22 hours over midnight."""
    early, late = sorted((first, second))
    start = datetime.combine(day, late, tzinfo=UTC)
    end = datetime.combine(day, early, tzinfo=UTC)
    with pytest.raises(SlotReversedError):
        check_slot(start, end)


# -- the API -----------------------------------------------------------------------------


@pytest.fixture
def lab(make_lab: LabFactory) -> Lab:
    return make_lab(control_time_limit=3600.0, idle_limit=None)


@pytest.fixture
def school(lab: Lab) -> None:
    """Tina teaches ctrl1 (ana, ben); Theo teaches ctrl2 (carla)."""
    for name, role in (("tina", "teacher"), ("theo", "teacher")):
        person(lab, name, role)
    for name in ("ana", "ben", "carla"):
        person(lab, name)
    course(lab, "tina", "ctrl1", ["ana", "ben"])
    course(lab, "theo", "ctrl2", ["carla"])


@pytest.mark.parametrize(
    ("language", "words"),
    [
        ("en", "ends before it starts"),
        ("pt-BR", "termina antes de começar"),
        ("es", "termina antes"),
    ],
)
def test_swapped_times_are_a_422_with_a_stable_code_in_each_language(
    lab: Lab, school: None, app_client: Clients, language: str, words: str
) -> None:
    tina = app_client("tina")
    answer = tina.post(
        "/api/bookings",
        json={"course": "ctrl1", "rigs": ["twin"], "startsAt": iso(600), "endsAt": iso(480)},
        headers={"Accept-Language": language},
    )
    assert answer.status_code == 422, answer.text
    assert answer.json()["code"] == "slot_ends_before_start"
    assert words in answer.json()["message"]
    naive = tina.post(
        "/api/bookings",
        json={
            "course": "ctrl1",
            "rigs": ["twin"],
            "startsAt": iso(60),
            "endsAt": iso(60 + 25 * 60),
        },
        headers={"Accept-Language": language},
    )
    assert naive.json()["code"] == "slot_too_long"


def test_a_teacher_may_say_a_slot_is_longer_than_a_day(
    lab: Lab, school: None, app_client: Clients
) -> None:
    tina = app_client("tina")
    body = {"course": "ctrl1", "rigs": ["twin"], "startsAt": iso(60), "endsAt": iso(60 + 48 * 60)}
    assert tina.post("/api/bookings", json=body).json()["code"] == "slot_too_long"
    long = tina.post("/api/bookings", json={**body, "longer": True})
    assert long.status_code == 201, long.text
    week = {**body, "endsAt": iso(60 + 8 * 24 * 60), "longer": True}
    assert tina.post("/api/bookings", json=week).json()["code"] == "slot_too_long"


def test_students_book_free_slots_for_themselves_within_the_weekly_quota(
    lab: Lab, school: None, app_client: Clients
) -> None:
    tina, ana, carla = app_client("tina"), app_client("ana"), app_client("carla")
    slot = {"rig": "twin", "startsAt": iso(60), "endsAt": iso(120)}
    # No quota yet: students book nothing.
    assert ana.get("/api/own-bookings").json() == []
    assert ana.post("/api/courses/ctrl1/own-bookings", json=slot).status_code == 403
    # Only the course's teachers set it.
    assert (
        ana.put("/api/courses/ctrl1/booking-quota", json={"minutesPerWeek": 90}).status_code == 403
    )
    theo = app_client("theo")
    assert (
        theo.put("/api/courses/ctrl1/booking-quota", json={"minutesPerWeek": 90}).status_code == 403
    )
    put = tina.put("/api/courses/ctrl1/booking-quota", json={"minutesPerWeek": 90})
    assert put.json() == {"course": "ctrl1", "minutesPerWeek": 90}
    assert tina.get("/api/courses/ctrl1/booking-quota").json()["minutesPerWeek"] == 90
    mine = ana.post("/api/courses/ctrl1/own-bookings", json=slot)
    assert mine.status_code == 201, mine.text
    assert (mine.json()["mine"], mine.json()["selfBooked"], mine.json()["course"]) == (
        True,
        True,
        "ctrl1",
    )
    [listed] = ana.get("/api/own-bookings").json()
    assert (listed["course"], listed["minutesPerWeek"], listed["usedMinutes"]) == ("ctrl1", 90, 60)
    # 60 of 90 used: 45 more minutes pass the quota, 30 fit.
    more = ana.post(
        "/api/courses/ctrl1/own-bookings",
        json={"rig": "other", "startsAt": iso(180), "endsAt": iso(225)},
    )
    assert more.status_code == 409
    assert more.json()["code"] == "booking_quota_exceeded"
    assert more.json()["quota"]["usedMinutes"] == 60
    fits = ana.post(
        "/api/courses/ctrl1/own-bookings",
        json={"rig": "other", "startsAt": iso(180), "endsAt": iso(210)},
    )
    assert fits.status_code == 201, fits.text
    # Next ISO week (Monday 2026-01-05): a fresh quota.
    monday = (datetime(2026, 1, 5, 9, tzinfo=UTC) - T0).total_seconds() / 60
    later = ana.post(
        "/api/courses/ctrl1/own-bookings",
        json={"rig": "twin", "startsAt": iso(monday), "endsAt": iso(monday + 90)},
    )
    assert later.status_code == 201, later.text
    # Not free: a clash, whoever booked it.
    ben = app_client("ben")
    taken = ben.post("/api/courses/ctrl1/own-bookings", json=slot)
    assert taken.json()["code"] == "booking_clash"
    # A student of another course, or of no quota, may not book in ctrl1.
    assert carla.post("/api/courses/ctrl1/own-bookings", json=slot).status_code == 403
    assert tina.post("/api/courses/ctrl1/own-bookings", json=slot).status_code == 403
    # The course's rigs only.
    assert tina.put("/api/courses/ctrl1/rigs", json={"rigs": ["twin"]}).status_code == 200
    off = ben.post(
        "/api/courses/ctrl1/own-bookings",
        json={"rig": "other", "startsAt": iso(300), "endsAt": iso(330)},
    )
    assert off.status_code == 403
    # Ana cancels her own; Ben may not cancel hers.
    booking = mine.json()["id"]
    assert ben.delete(f"/api/bookings/{booking}").status_code == 403
    assert ana.delete(f"/api/bookings/{booking}").status_code == 204
    # Others see a classmate's booking as the course's.
    [seen] = [
        b
        for b in ben.get("/api/bookings", params={"from": iso(0), "to": iso(600)}).json()
        if b["id"] == fits.json()["id"]
    ]
    assert (seen["selfBooked"], seen["mine"]) == (True, False)
    # Next term's copy keeps the quota, not last term's students' own bookings.
    copied = tina.post("/api/courses/ctrl1/copy", json={"name": "ctrl1-next", "shiftDays": 7})
    assert copied.status_code == 201, copied.text
    assert copied.json()["bookings"] == 0
    assert tina.get("/api/courses/ctrl1-next/booking-quota").json()["minutesPerWeek"] == 90


def test_a_students_quota_counts_the_weeks_of_the_labs_time_zone(make_lab: LabFactory) -> None:
    """Sunday evening in São Paulo is Monday in UTC: it counts in Sunday's week there."""
    from thermolab.errors import BookingQuotaError

    lab = make_lab(control_time_limit=3600.0, idle_limit=None, time_zone="America/Sao_Paulo")
    tina, ana = person(lab, "tina", "teacher"), person(lab, "ana")
    course(lab, "tina", "ctrl1", ["ana"])
    lab.booking_tools.set_quota(tina, "ctrl1", 60)
    sp = ZoneInfo("America/Sao_Paulo")

    def book(day: int, hour: int) -> Any:
        start = datetime(2026, 1, day, hour, tzinfo=sp)
        return lab.booking_tools.book_own(ana, "ctrl1", "twin", start, start + timedelta(hours=1))

    sunday_evening = book(11, 22)  # 2026-01-12 01:00 UTC
    assert sunday_evening.starts_at.astimezone(UTC).weekday() == 0  # a Monday in UTC
    with pytest.raises(BookingQuotaError) as refused:
        book(10, 10)  # Saturday: the same week in São Paulo, full
    assert refused.value.quota["weekStartsAt"] == "2026-01-05T03:00:00+00:00"
    assert "the week from 2026-01-05" in str(refused.value)
    book(12, 10)  # Monday 10:00 there: a new week, though the same UTC week as Sunday's
    [listed] = lab.booking_tools.own_courses(ana)
    assert listed.week_starts_at == datetime(2026, 1, 1, 3, tzinfo=UTC) - timedelta(days=3)


def test_a_weekly_series_books_each_week_and_lists_the_clashes(
    lab: Lab, school: None, app_client: Clients
) -> None:
    tina, theo = app_client("tina"), app_client("theo")
    # Theo holds the rig in the third week.
    third = 60 + 14 * 24 * 60
    taken = theo.post(
        "/api/bookings",
        json={
            "course": "ctrl2",
            "rigs": ["twin"],
            "startsAt": iso(third),
            "endsAt": iso(third + 30),
        },
    )
    assert taken.status_code == 201
    body = {
        "course": "ctrl1",
        "rigs": ["twin", "other"],
        "startsAt": iso(60),
        "endsAt": iso(120),
        "until": "2026-01-29",
    }
    refused = tina.post("/api/booking-series", json=body)
    assert refused.status_code == 409, refused.text
    assert refused.json()["code"] == "booking_series_clash"
    [clash] = refused.json()["clashes"]
    assert clash["startsAt"].startswith("2026-01-15T01:00")
    assert clash["slot"]["course"] == "ctrl2"
    window = {"from": iso(0), "to": iso(40 * 24 * 60)}
    assert [
        b for b in tina.get("/api/bookings", params=window).json() if b["course"] == "ctrl1"
    ] == []
    booked = tina.post("/api/booking-series", json={**body, "skipClashes": True})
    assert booked.status_code == 201, booked.text
    starts = [b["startsAt"][:16] for b in booked.json()["booked"]]
    assert starts == [
        "2026-01-01T01:00",
        "2026-01-08T01:00",
        "2026-01-22T01:00",
        "2026-01-29T01:00",
    ]
    assert len(booked.json()["skipped"]) == 1
    series = {b["series"] for b in booked.json()["booked"]}
    assert len(series) == 1
    assert None not in series
    # Each occurrence is a normal booking: cancelled alone.
    first = booked.json()["booked"][0]["id"]
    assert tina.delete(f"/api/bookings/{first}").status_code == 204
    ours = [b for b in tina.get("/api/bookings", params=window).json() if b["course"] == "ctrl1"]
    assert len(ours) == 3
    # Teachers only; a date before the first week is a 422.
    assert app_client("ana").post("/api/booking-series", json=body).status_code == 403
    early = tina.post("/api/booking-series", json={**body, "until": "2025-12-01"})
    assert early.status_code == 422


def _series_in(tina: TestClient, first: datetime, until: str, **extra: Any) -> list[datetime]:
    body = {
        "course": "ctrl1",
        "rigs": ["twin"],
        "startsAt": first.isoformat(),
        "endsAt": (first + timedelta(hours=1)).isoformat(),
        "until": until,
        **extra,
    }
    booked = tina.post("/api/booking-series", json=body)
    assert booked.status_code == 201, booked.text
    slots = [
        (datetime.fromisoformat(b["startsAt"]), datetime.fromisoformat(b["endsAt"]))
        for b in booked.json()["booked"]
    ]
    assert all(b - a == timedelta(hours=1) for a, b in slots)  # each as long as the first
    return [a for a, _ in slots]


@pytest.mark.parametrize(
    ("zone", "first"),
    [
        # Clocks go forward on 8 March 2026 in New York, on 29 March in Lisbon ...
        ("America/New_York", datetime(2026, 3, 2, 14, tzinfo=UTC)),
        ("Europe/Lisbon", datetime(2026, 3, 23, 10, tzinfo=UTC)),
        # ... and back on 5 April in Santiago (Chile keeps daylight saving; Brazil does not).
        ("America/Santiago", datetime(2026, 3, 30, 12, tzinfo=UTC)),
    ],
)
def test_a_weekly_series_keeps_its_local_hour_across_a_change_of_daylight_saving(
    lab: Lab, school: None, app_client: Clients, zone: str, first: datetime
) -> None:
    tina = app_client("tina")
    tz = ZoneInfo(zone)
    last = (first + timedelta(weeks=2)).astimezone(tz).date().isoformat()
    starts = _series_in(tina, first, last, zone=zone)
    local = [a.astimezone(tz) for a in starts]
    # The same weekday and wall-clock time every week ...
    assert [(t.weekday(), t.time()) for t in local] == [
        (first.astimezone(tz).weekday(), first.astimezone(tz).time())
    ] * 3
    assert local[0].utcoffset() != local[-1].utcoffset()  # (the change is in the series)
    # ... so the UTC instants are an hour off a week's apart across the change.
    gaps = [starts[1] - starts[0], starts[2] - starts[1]]
    assert timedelta(weeks=1) in gaps
    assert abs(gaps[0] + gaps[1] - timedelta(weeks=2)) == timedelta(hours=1)


def test_a_series_without_a_zone_keeps_the_labs_local_hour(make_lab: LabFactory) -> None:
    lab = make_lab(control_time_limit=3600.0, idle_limit=None, time_zone="Europe/Lisbon")
    tina = person(lab, "tina", "teacher")
    course(lab, "tina", "ctrl1", ["ana"])
    # 10:00 in Lisbon, a week before and a week after summer time starts (29 March 2026).
    first = datetime(2026, 3, 23, 10, tzinfo=UTC)
    result = lab.booking_tools.book_series(
        tina, "ctrl1", ["twin"], first, first + timedelta(hours=1), date(2026, 3, 30)
    )
    assert result.zone == "Europe/Lisbon"
    starts = [b.starts_at for b in result.booked]
    assert [a.astimezone(UTC).hour for a in starts] == [10, 9]
    assert {a.astimezone(ZoneInfo("Europe/Lisbon")).hour for a in starts} == {10}


@pytest.mark.parametrize(
    ("language", "words"),
    [("en", "not a known IANA"), ("pt-BR", "não é um fuso horário IANA"), ("es", "no es una")],
)
def test_an_unknown_zone_is_a_422_with_a_stable_code_and_nothing_booked(
    lab: Lab, school: None, app_client: Clients, language: str, words: str
) -> None:
    tina = app_client("tina", headers={"Accept-Language": language})
    body = {
        "course": "ctrl1",
        "rigs": ["twin"],
        "startsAt": iso(60),
        "endsAt": iso(120),
        "until": "2026-01-29",
    }
    for zone in ("Mars/Olympus", "../../etc/passwd", "America/Sao Paulo"):
        refused = tina.post("/api/booking-series", json={**body, "zone": zone})
        assert refused.status_code == 422, refused.text
        assert refused.json()["code"] == "time_zone_unknown"
        assert zone in refused.json()["detail"]
        assert words in refused.json()["message"]
    window = {"from": iso(0), "to": iso(40 * 24 * 60)}
    assert tina.get("/api/bookings", params=window).json() == []


def test_a_calendar_feed_is_read_without_a_login_and_revoked(
    lab: Lab, school: None, app_client: Clients
) -> None:
    tina, ana = app_client("tina"), app_client("ana")
    tina.post(
        "/api/bookings",
        json={
            "course": "ctrl1",
            "rigs": ["twin"],
            "startsAt": iso(60),
            "endsAt": iso(120),
            "note": "Lab 1",
        },
    )
    app_client("theo").post(
        "/api/bookings",
        json={"course": "ctrl2", "rigs": ["other"], "startsAt": iso(60), "endsAt": iso(120)},
    )
    made = ana.post("/api/calendar-feeds", json={})
    assert made.status_code == 201, made.text
    url = made.json()["url"]
    assert url.endswith(".ics")
    assert "/api/calendar/" in url
    # Another course's feed: only its members.
    assert ana.post("/api/calendar-feeds", json={"course": "ctrl2"}).status_code == 403
    anonymous = app_client()
    path = url[url.index("/api/calendar/") :]
    answer = anonymous.get(path)
    assert answer.status_code == 200, answer.text
    assert answer.headers["content-type"].startswith("text/calendar")
    events = Calendar.from_ical(answer.content).walk("VEVENT")
    assert [(str(e["summary"]), e.decoded("dtstart")) for e in events] == [
        ("Course ctrl1: twin", T0 + timedelta(hours=1))
    ]
    assert str(events[0]["description"]) == "Lab 1"
    # Listed without its secret; revoked, the address is gone.
    [listed] = ana.get("/api/calendar-feeds").json()
    assert listed["url"] is None
    assert listed["lastReadAt"] is not None
    assert app_client("ben").delete(f"/api/calendar-feeds/{listed['id']}").status_code == 404
    assert ana.delete(f"/api/calendar-feeds/{listed['id']}").status_code == 204
    assert anonymous.get(path).status_code == 404
    assert anonymous.get("/api/calendar/" + "x" * 43 + ".ics").status_code == 404
    # Only a hash is stored: the token appears nowhere in the database.
    course_feed = tina.post("/api/calendar-feeds", json={"course": "ctrl1"}).json()
    token = course_feed["url"].rsplit("/", 1)[1].removesuffix(".ics")
    with lab.db.read() as session:
        assert all(token not in f.token_hash for f in session.query(CalendarFeed))


# -- reminders, against a real SMTP server ----------------------------------------------


class _Inbox:
    def __init__(self) -> None:
        self.messages: list[tuple[list[str], str]] = []

    async def handle_DATA(self, server: Any, session: Any, envelope: Any) -> str:  # noqa: N802
        self.messages.append((list(envelope.rcpt_tos), envelope.content.decode()))
        return "250 OK"


@pytest.fixture
def smtp_server() -> Iterator[tuple[_Inbox, int]]:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    inbox = _Inbox()
    controller = Controller(inbox, hostname="127.0.0.1", port=port)
    controller.start()
    try:
        yield inbox, port
    finally:
        controller.stop()


def test_a_reminder_is_mailed_once_before_a_booking_even_across_a_restart(
    make_lab: LabFactory, clock: ManualClock, smtp_server: tuple[_Inbox, int]
) -> None:
    inbox, port = smtp_server
    smtp = SmtpConfig("127.0.0.1", port, sender="lab@example.org")
    lab = make_lab(smtp=smtp)
    tina, ana, ben = (person(lab, "tina", "teacher"), person(lab, "ana"), person(lab, "ben"))
    course(lab, "tina", "ctrl1", ["ana", "ben"])
    lab.bookings.create(tina, "ctrl1", ["twin"], T0 + timedelta(hours=2), T0 + timedelta(hours=3))
    lab.reminders.subscribe(ana, "ana@example.org", 30, "pt-BR")  # the page's language
    # Not due yet (two hours ahead, 30 minutes asked).
    assert lab.reminders.send_due() == 0
    clock.advance(91 * 60)
    assert lab.reminders.send_due() == 1
    [(to, raw)] = inbox.messages
    mail = message_from_string(raw, policy=default)
    assert isinstance(mail, EmailMessage)
    text = mail.get_content()
    assert to == ["ana@example.org"]
    # The lab's time zone is UTC (the default), named.
    assert "Uma reserva de Course ctrl1 (ctrl1) em twin: 01/01/2026, 02:00–03:00 (UTC)." in text
    assert str(mail["Subject"]).startswith("[ThermoLab] Lembrete: Course ctrl1")
    # Again, and from a new service over the same database (a restart): nothing more.
    assert lab.reminders.send_due() == 0
    restarted = ReminderService(lab.db, clock, smtp, "ThermoLab")
    assert restarted.send_due() == 0
    assert len(inbox.messages) == 1
    # Ben has no address: none for him. A lab without [smtp] refuses addresses.
    assert all("ben" not in to[0] for to, _ in inbox.messages)
    without = ReminderService(lab.db, clock, None, "ThermoLab")
    assert without.settings(ben).available is False
    with pytest.raises(ValueError, match="no mail server"):
        without.subscribe(ben, "ben@example.org", 10)
    # Forgetting Ana (her runs kept under a pseudonym) forgets her address too.
    forget_person(lab.db, "ana", "keep", "unusable")
    with lab.db.read() as session:
        assert session.get(ReminderAddress, ana.user_id) is None


def test_a_reminder_states_the_slot_in_the_labs_time_zone_in_the_readers_language(
    make_lab: LabFactory, clock: ManualClock, smtp_server: tuple[_Inbox, int]
) -> None:
    inbox, port = smtp_server
    smtp = SmtpConfig("127.0.0.1", port, sender="lab@example.org")
    lab = make_lab(smtp=smtp, time_zone="America/Sao_Paulo")
    tina = person(lab, "tina", "teacher")
    readers = {"ana": "pt-BR", "ben": "en", "carla": "es"}
    people = {name: person(lab, name) for name in readers}
    course(lab, "tina", "ctrl1", list(readers))
    # 20:00 to 21:00 UTC is 17:00 to 18:00 in São Paulo (UTC-3, no daylight saving).
    start = T0 + timedelta(hours=20)
    lab.bookings.create(tina, "ctrl1", ["twin"], start, start + timedelta(hours=1))
    for name, language in readers.items():
        lab.reminders.subscribe(people[name], f"{name}@example.org", 30, language)
    clock.advance(19.6 * 3600)
    assert lab.reminders.send_due() == 3
    bodies: dict[str, tuple[str, str]] = {}
    for to, raw in inbox.messages:
        mail = message_from_string(raw, policy=default)
        assert isinstance(mail, EmailMessage)
        bodies[to[0].split("@")[0]] = (str(mail["Subject"]), mail.get_content())
    assert bodies["ana"][1].startswith(
        "Uma reserva de Course ctrl1 (ctrl1) em twin: 01/01/2026, 17:00–18:00 (America/Sao_Paulo)."
    )
    assert bodies["ben"][1].startswith(
        "A booking of Course ctrl1 (ctrl1) on twin: 2026-01-01, 17:00–18:00 (America/Sao_Paulo)."
    )
    assert bodies["carla"][1].startswith(
        "Una reserva de Course ctrl1 (ctrl1) en twin: 01/01/2026, 17:00–18:00 (America/Sao_Paulo)."
    )
    assert bodies["ben"][0] == (
        "[ThermoLab] Reminder: Course ctrl1, 2026-01-01, 17:00–18:00 (America/Sao_Paulo)"
    )
    assert all("UTC" not in text for _, text in bodies.values())


def test_reminder_settings_through_the_api(lab: Lab, school: None, app_client: Clients) -> None:
    ana = app_client("ana")
    assert ana.get("/api/reminders").json() == {
        "available": False,
        "email": None,
        "minutesBefore": None,
    }
    refused = ana.put("/api/reminders", json={"email": "ana@example.org", "minutesBefore": 30})
    assert refused.status_code == 422
    assert ana.delete("/api/reminders").status_code == 404
