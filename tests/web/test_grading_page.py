"""A teacher's grading tools in the browser (#24 item 7): groups, override, extension.

A teacher (in Brazilian Portuguese) forms a lab group of two students on an
assignment's page; one member hands in her run for both (through the API);
the teacher reads both members marked the same, overrides one member's mark
with a comment (typed with a decimal comma) and extends the deadline of a
third student. The overridden student reads (in English) the teacher's mark,
the comment, the automatic mark beside them, the group and who handed in;
the group mate opens the run handed in for her (read only: its page, its
samples); the extended one reads (in Spanish) their own deadline. One lab for the
module; axe finds no serious violation on the teacher's page.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from .axe import serious_violations
from .conftest import LabServer, password

pytestmark = pytest.mark.browser

# Names no other browser test logs in with: conftest caches each name's login cookie.
USERS = {"gina": "teacher", "rui.gr": "student", "sol.gr": "student", "teo.gr": "student"}
CONFIG = """\
title = "ThermoLab grading"

[[rigs]]
id = "twin-g"
title = "Grading twin"
spec = "sim"
"""


def _client(lab: LabServer, user: str) -> httpx.Client:
    client = httpx.Client(base_url=lab.url, timeout=30)
    login = client.post("/api/session", json={"username": user, "password": password(user)})
    assert login.status_code == 200, login.text
    return client


@pytest.fixture(scope="module")
def grading_lab(
    tmp_path_factory: pytest.TempPathFactory, browser: Any, start_lab: Any
) -> Iterator[tuple[LabServer, int, int]]:
    """A course of three students, an open assignment, and rui's finished run."""
    with start_lab(tmp_path_factory.mktemp("grading"), USERS, config=CONFIG) as lab:
        teacher, rui = _client(lab, "gina"), _client(lab, "rui.gr")
        made = teacher.post("/api/courses", json={"name": "lab1", "title": "Laboratório 1"})
        assert made.status_code == 201, made.text
        roster = "username,display_name\nrui.gr,Rui\nsol.gr,Sol\nteo.gr,Teo\n"
        assert teacher.put("/api/courses/lab1/roster", content=roster.encode()).status_code == 200
        body = {
            "title": "Degrau",
            "rig": "twin-g",
            "methods": ["lsm"],
            "deadline": "2100-01-01T00:00:00Z",
        }
        assignment = teacher.post("/api/courses/lab1/assignments", json=body)
        assert assignment.status_code == 201, assignment.text
        assert rui.post("/api/rigs/twin-g/control").json()["access"]["role"] == "controller"
        started = rui.post(
            "/api/rigs/twin-g/runs",
            json={"dt": 1, "samples": 60, "signal": "step:0:5@2", "methods": ["lsm"]},
        )
        assert started.status_code == 201, started.text
        run_id = started.json()["id"]
        deadline = time.monotonic() + 60
        while rui.get(f"/api/runs/{run_id}").json()["status"] == "running":
            assert time.monotonic() < deadline, "the run did not end"
            time.sleep(0.1)  # real time: the server's run thread
        rui.delete("/api/rigs/twin-g/control")
        for client in (teacher, rui):
            client.close()
        yield lab, assignment.json()["id"], run_id


def test_a_teacher_groups_overrides_and_extends_and_students_read_it(
    grading_lab: tuple[LabServer, int, int], context_for: Any
) -> None:
    lab, aid, run_id = grading_lab
    teacher = context_for(lab, "gina", locale="pt-BR", bypass_csp=True)
    try:
        page = teacher.new_page()
        page.goto(f"{lab.url}/#/assignments/{aid}")
        page.wait_for_selector("#standings tr[data-student='teo.gr']")
        # A lab group of rui and sol.
        page.fill("#group-name", "Bancada 1")
        page.check("#group-members input[value='rui.gr']")
        page.check("#group-members input[value='sol.gr']")
        page.click("#group-form button[type=submit]")
        page.wait_for_selector("#group-list li[data-group='Bancada 1']")
        assert page.inner_text("#group-form-result") == "Grupo Bancada 1 formado."
        assert "Rui (rui.gr), Sol (sol.gr)" in page.inner_text("#group-list")
        # rui hands in his run for the group: both are marked the same.
        rui = _client(lab, "rui.gr")
        try:
            handed = rui.post(
                f"/api/assignments/{aid}/submissions",
                json={"runId": run_id, "K": 0.1, "tau": 200.0, "theta": 0.0},
            )
        finally:
            rui.close()
        assert handed.status_code == 201, handed.text
        automatic = handed.json()["mark"]
        page.reload()
        sol_row = page.locator("#standings tr[data-student='sol.gr']")
        sol_row.wait_for()
        rui_row = page.locator("#standings tr[data-student='rui.gr']")
        assert "Bancada 1" in sol_row.inner_text()
        sol_hand_in = page.locator("#submissions tr[data-student='sol.gr']").inner_text()
        assert "entregue por rui.gr pelo grupo" in sol_hand_in
        mark_cell = "[data-testid=final-mark]"
        assert sol_row.locator(mark_cell).inner_text() == rui_row.locator(mark_cell).inner_text()

        # Override sol's mark with a comment, typed with a decimal comma.
        page.select_option("#override-student", "sol.gr")
        page.fill("#override-mark", "7,5")
        page.fill("#override-comment", "Não estava na bancada durante o ensaio.")
        page.click("#override-form button[type=submit]")
        page.wait_for_selector("#standings tr[data-student='sol.gr'][data-overridden='true']")
        assert "7,5" in page.inner_text("#override-form-result")
        sol_row = page.locator("#standings tr[data-student='sol.gr']")
        assert sol_row.locator(mark_cell).inner_text() == "Nota: 7,5 de 10"
        assert "Não estava na bancada" in sol_row.inner_text()
        # Extend teo's deadline by a week.
        page.select_option("#extend-student", "teo.gr")
        page.fill("#extend-deadline", "2100-01-08T12:00")
        page.click("#extend-form button[type=submit]")
        page.wait_for_selector("#standings tr[data-student='teo.gr'][data-extended='true']")
        assert "prorrogado" in page.locator("#standings tr[data-student='teo.gr']").inner_text()
        assert serious_violations(page) == []
    finally:
        teacher.close()

    student = context_for(lab, "sol.gr", locale="en-GB")
    try:
        page = student.new_page()
        page.goto(f"{lab.url}/#/assignments/{aid}")
        page.wait_for_selector("#my-terms")
        assert page.inner_text("[data-testid=override]") == "Your teacher's mark: 7.5 out of 10"
        assert page.inner_text("[data-testid=override-comment]") == (
            "Your teacher's comment: Não estava na bancada durante o ensaio."
        )
        assert automatic is not None
        assert "Automatic mark:" in page.inner_text("#my-terms")
        assert page.inner_text("[data-testid=group]") == (
            "You hand in with your lab group Bancada 1: rui.gr, sol.gr."
        )
        assert page.inner_text("[data-testid=handed-in-by]") == "handed in by rui.gr for the group"
        assert page.is_visible("[data-testid=mark]")  # the hand-in's automatic feedback stays
        # rui's run, handed in for the group, opens for his mate: read only.
        assert page.inner_text("[data-testid=handed-in-run]") == f"Run {run_id}"
        page.click("[data-testid=handed-in-run]")
        page.wait_for_selector("[data-testid=csv-link]")
        assert "rui.gr" in page.inner_text("dl.facts")
        assert page.locator("#run-charts").is_visible()
        assert page.locator(".error").count() == 0
        csv_link = page.get_attribute("[data-testid=csv-link]", "href")
        assert csv_link is not None
        assert page.request.get(f"{lab.url}{csv_link}").status == 200
    finally:
        student.close()

    student = context_for(lab, "teo.gr", locale="es")
    try:
        page = student.new_page()
        page.goto(f"{lab.url}/#/assignments/{aid}")
        page.wait_for_selector("[data-testid=extended]")
        extended = page.inner_text("[data-testid=extended]")
        assert extended.startswith("Su plazo se prorrogó hasta 8/1/00, 12:00")  # es short date
    finally:
        student.close()
