"""Class analytics in the browser (#10 item 6), in Brazilian Portuguese and English.

Two students of a course make real runs on a twin through the JSON API (one
waits in the queue while the other controls the rig); the teacher opens the
course's analytics page: the figures on the page are the API's, written in
the page's language; each chart has its table; both CSV files download; axe
finds no serious violation; on a 375-px phone nothing but the tables'
own regions scrolls sideways.
"""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from .axe import serious_violations
from .conftest import LabServer, password

pytestmark = pytest.mark.browser

# Names no other browser test logs in with: conftest caches each name's login cookie.
USERS = {"tomas": "teacher", "ana.an": "student", "bruno.an": "student"}
CONFIG = """\
title = "ThermoLab analytics"

[[rigs]]
id = "twin-a"
title = "Analytics twin"
spec = "sim"
"""
WORDS = {
    "pt-BR": {"locale": "pt-BR", "title": "Análise: Controle I", "mark": ","},
    "en": {"locale": "en-GB", "title": "Analytics: Controle I", "mark": "."},
}


def _client(lab: LabServer, user: str) -> httpx.Client:
    client = httpx.Client(base_url=lab.url, timeout=30)
    login = client.post("/api/session", json={"username": user, "password": password(user)})
    assert login.status_code == 200, login.text
    return client


def _run(client: httpx.Client, rig: str, samples: int) -> dict[str, Any]:
    """START a short step test on ``rig`` (the caller controls it) and wait for its end."""
    started = client.post(
        f"/api/rigs/{rig}/runs",
        json={"dt": 1, "samples": samples, "signal": "step:0:5@2", "methods": ["srm", "lsm"]},
    )
    assert started.status_code == 201, started.text
    run_id = started.json()["id"]
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        run: dict[str, Any] = client.get(f"/api/runs/{run_id}").json()
        if run["status"] != "running" and run.get("results"):
            return run
        time.sleep(0.1)  # real time: the server's run thread
    raise AssertionError(f"run {run_id} did not end")


@pytest.fixture(scope="module")
def class_lab(
    tmp_path_factory: pytest.TempPathFactory, browser: Any, start_lab: Any
) -> Iterator[LabServer]:
    """A lab where ana made two runs and bruno one, after waiting for ana's turn."""
    with start_lab(tmp_path_factory.mktemp("analytics"), USERS, config=CONFIG) as lab:
        teacher, ana, bruno = (_client(lab, u) for u in USERS)
        assert (
            teacher.post("/api/courses", json={"name": "ctrl1", "title": "Controle I"}).status_code
            == 201
        )
        roster = "username,display_name\nana.an,Ana Análise\nbruno.an,Bruno Brandão\n"
        assert teacher.put("/api/courses/ctrl1/roster", content=roster.encode()).status_code == 200
        assert ana.post("/api/rigs/twin-a/control").json()["access"]["role"] == "controller"
        assert bruno.post("/api/rigs/twin-a/control").json()["access"]["queuePosition"] == 1
        _run(ana, "twin-a", 40)
        handed = _run(ana, "twin-a", 60)
        assert ana.delete("/api/rigs/twin-a/control").status_code in (200, 204)
        _run(bruno, "twin-a", 40)
        assert bruno.delete("/api/rigs/twin-a/control").status_code in (200, 204)
        # An assignment still open: ana hands in her second run, bruno nothing.
        set_ = teacher.post(
            "/api/courses/ctrl1/assignments",
            json={
                "title": "Step test",
                "rig": "twin-a",
                "methods": ["lsm"],
                "deadline": "2100-01-01T00:00:00Z",
            },
        )
        assert set_.status_code == 201, set_.text
        lsm = handed["results"]["lsm"]["latest"]
        hand_in = ana.post(
            f"/api/assignments/{set_.json()['id']}/submissions",
            json={"runId": handed["id"], "K": lsm["K"] or 0.1, "tau": lsm["tau"] or 100.0},
        )
        assert hand_in.status_code == 201, hand_in.text
        for client in (teacher, ana, bruno):
            client.close()
        yield lab


@pytest.mark.parametrize("language", list(WORDS))
def test_the_teacher_sees_the_classs_figures_charts_and_csv(
    language: str, class_lab: LabServer, context_for: Any, artifacts: Path
) -> None:
    words = WORDS[language]
    suffix = language.lower().replace("-", "")
    context = context_for(
        class_lab, "tomas", locale=words["locale"], bypass_csp=True, accept_downloads=True
    )
    try:
        page = context.new_page()
        page.goto(f"{class_lab.url}/#/courses?course=ctrl1")
        page.click("#course-analytics")
        page.wait_for_selector("#analytics-student-table tr[data-student]")
        assert page.inner_text("h1") == words["title"]
        api = page.evaluate(
            "async () => (await fetch('/api/courses/ctrl1/analytics',"
            " {headers: {Accept: 'application/json'}})).json()"
        )
        by = {s["username"]: s for s in api["students"]}
        assert sorted(by) == ["ana.an", "bruno.an"]
        assert (by["ana.an"]["runs"], by["bruno.an"]["runs"]) == (2, 1)
        assert by["ana.an"]["turns"] == by["bruno.an"]["turns"] == 1
        for name, student in by.items():
            row = page.locator(f'tr[data-student="{name}"]')
            cell = row.locator('[data-field="controlSeconds"]')
            assert float(cell.get_attribute("data-value") or "nan") == pytest.approx(
                student["controlSeconds"]
            )
            assert (
                words["mark"] in cell.inner_text()
            )  # minutes to one decimal, in the language's form
            assert row.locator('[data-field="runs"]').get_attribute("data-value") == str(
                student["runs"]
            )
            for result in student["results"]:
                item = row.locator(f'li[data-method="{result["method"]}"]')
                assert item.get_attribute("data-trusted") == str(result["trusted"]).lower()
                assert float(item.get_attribute("data-k") or "nan") == pytest.approx(result["K"])
        assert {r["method"] for r in by["ana.an"]["results"]} == {"srm", "lsm"}
        # The assignment column: ana handed in the one assignment, bruno did not.
        assert by["ana.an"]["assignments"]["submitted"] == 1
        assert by["bruno.an"]["assignments"] == {
            "assigned": 1,
            "submitted": 0,
            "late": 0,
            "marked": 0,
            "meanMark": None,
        }
        for name, student in by.items():
            text = page.locator(
                f'tr[data-student="{name}"] [data-field="assignments"]'
            ).inner_text()
            assert text.startswith(f"{student['assignments']['submitted']} ")
            assert str(student["assignments"]["assigned"]) in text
        # The mean mark is a percentage of the maximum, as the spreadsheet's heading says.
        mean = page.locator('tr[data-student="ana.an"] [data-field="assignments"]').inner_text()
        assert f"{by['ana.an']['assignments']['meanMark']:.0f}%" in mean.replace("\u00a0", "")
        (rig,) = api["rigs"]
        assert (rig["rig"], rig["runs"], rig["students"], rig["turns"]) == ("twin-a", 3, 2, 2)
        assert rig["waits"]["count"] == 2  # ana got the rig at once, bruno after ana's turn
        assert rig["waits"]["p90"] > rig["waits"]["median"] >= 0
        assert rig["poweredSeconds"] > 0
        rig_row = page.locator('tr[data-rig="twin-a"]')
        assert float(
            rig_row.locator('[data-field="waitMedian"]').get_attribute("data-value") or "nan"
        ) == pytest.approx(rig["waits"]["median"])
        assert rig_row.locator('[data-field="runs"]').inner_text() == "3"

        # Each chart has its table: every student (or rig), named.
        charts = page.locator("#analytics-body figure.chart")
        assert charts.count() == 4
        charts.first.locator("button.chart-toggle").click()
        names = charts.first.locator(".chart-table tbody th").all_inner_texts()
        assert names == ["Ana Análise", "Bruno Brandão"]
        assert serious_violations(page) == []
        page.screenshot(path=str(artifacts / f"analytics-{suffix}.png"), full_page=True)

        # Both tables download as CSV, the figures of the same window.
        with page.expect_download() as students_file:
            page.click("#analytics-students-csv")
        rows = list(
            csv.DictReader(io.StringIO(Path(students_file.value.path()).read_text("utf-8")))
        )
        assert [(r["username"], r["runs"]) for r in rows] == [("ana.an", "2"), ("bruno.an", "1")]
        assert rows[0]["display_name"] == "Ana Análise"
        assert [(r["assignments_assigned"], r["assignments_submitted"]) for r in rows] == [
            ("1", "1"),
            ("1", "0"),
        ]
        with page.expect_download() as rigs_file:
            page.click("#analytics-rigs-csv")
        rigs = list(csv.DictReader(io.StringIO(Path(rigs_file.value.path()).read_text("utf-8"))))
        assert [(r["rig"], r["runs"], r["waits"]) for r in rigs] == [("twin-a", "3", "2")]
        # Beside it, the spreadsheet form in the page's language (";" where "," is decimal).
        with page.expect_download() as sheet_file:
            page.click("#analytics-students-csv-sheet")
        sheet = Path(sheet_file.value.path()).read_text("utf-8")
        assert sheet.startswith("\ufeff")
        separator = ";" if words["mark"] == "," else ","
        people = list(csv.reader(io.StringIO(sheet.removeprefix("\ufeff")), delimiter=separator))
        assert people[0][0] == {"pt-BR": "Nome de login", "en": "Login name"}[language]
        assert [(r[0], r[1]) for r in people[1:]] == [
            ("ana.an", "Ana Análise"),
            ("bruno.an", "Bruno Brandão"),
        ]

        # A 375-px phone: the page does not scroll sideways (the tables scroll in their regions).
        page.set_viewport_size({"width": 375, "height": 812})
        page.wait_for_timeout(200)
        width = page.evaluate("() => document.documentElement.scrollWidth")
        assert width <= 375, width
        page.screenshot(path=str(artifacts / f"analytics-phone-{suffix}.png"), full_page=True)
    finally:
        context.close()


def test_a_student_is_told_the_page_is_for_teachers(class_lab: LabServer, context_for: Any) -> None:
    context = context_for(class_lab, "ana.an")
    try:
        page = context.new_page()
        page.goto(f"{class_lab.url}/#/analytics?course=ctrl1")
        page.wait_for_selector("#main p.error")
        assert page.locator("#analytics-student-table").count() == 0
    finally:
        context.close()
