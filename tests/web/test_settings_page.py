"""Teacher settings in the browser (#10): a teacher changes the turn limit, a student sees it.

A lab of its own (one twin, a technician's cap on the longest run), in
Brazilian Portuguese and English: the form is the server's declarations in
the page's language (the twin's speed-up among them, the lab's
``--speedup``), a value out of range is refused beside its field with the
range, a saved value is the one in force, and the student's rig page shows
the new turn length and, under the rig's name, the twin's pace. The teacher's
view passes axe with the form. The audit log lists the teacher's changes (rig
settings; a course, its list, its rigs).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .axe import serious_violations
from .conftest import LabServer, audited

pytestmark = pytest.mark.browser

CONFIG = """\
title = "ThermoLab settings"

[[rigs]]
id = "twin"
title = "Digital twin of the paper's box"
spec = "sim"
caps = { max_run_seconds = 7200 }
"""

CASES = {
    "pt-BR": {
        "locale": "pt-BR",
        "heading": "Configurações desta bancada",
        "typed": "150",
        "shown": "2 minutos 30 segundos",
        "range": "Limite do turno deve ser",
        "speedup": "Aceleração do gêmeo",
        "pace": "Gêmeo digital 200× mais rápido que o tempo real: o primeiro ensaio do artigo "
        "(2.000 s) leva 10 segundos. Um turno dura 2 minutos 30 segundos; um ensaio em andamento "
        "no fim do turno vai até o fim.",
    },
    "en": {
        "locale": "en-GB",
        "heading": "Settings of this rig",
        "typed": "90",
        "shown": "1 minute 30 seconds",
        "range": "Turn limit must be",
        "speedup": "Twin speed-up",
        "pace": "Digital twin at 200× real time: the paper's first experiment (2,000 s) takes "
        "10 seconds. A turn lasts 1 minute 30 seconds; a run going at its end goes on to its end.",
    },
}


@pytest.fixture(scope="module")
def settings_lab(
    tmp_path_factory: pytest.TempPathFactory, browser: Any, start_lab: Any
) -> Iterator[LabServer]:
    users = {"tess": "teacher", "sam": "student"}
    with start_lab(tmp_path_factory.mktemp("settings-lab"), users, config=CONFIG) as server:
        yield server


def _login(browser: Any, lab: LabServer, user: str, locale: str) -> Any:
    """A context of this lab logged in as ``user`` (the session's shared logins are another
    lab's)."""
    context = browser.new_context(locale=locale, bypass_csp=True)
    page = context.new_page()
    page.goto(f"{lab.url}/")
    page.fill("#login-username", user)
    page.fill("#login-password", lab.password(user))
    page.click("form button[type=submit]")
    page.wait_for_selector("#nav:not([hidden])")
    page.close()
    return context


@pytest.mark.parametrize("language", list(CASES))
def test_a_teacher_changes_the_turn_limit_and_the_student_page_shows_it(
    language: str, browser: Any, settings_lab: LabServer, artifacts: Path
) -> None:
    case = CASES[language]
    teacher = _login(browser, settings_lab, "tess", case["locale"])
    student = _login(browser, settings_lab, "sam", case["locale"])
    field = "#settings-twin-control_time_limit"
    try:
        page = teacher.new_page()
        page.goto(f"{settings_lab.url}/#/teacher")
        page.wait_for_selector(field)
        assert page.inner_text("#settings-twin") == case["heading"]
        form = page.locator('[data-settings="twin"] form')
        version = int(form.get_attribute("data-version") or "0")
        # The technician's cap is the longest run's range.
        assert "7" in page.inner_text("#settings-twin-max_run_seconds-hint")
        # The twin's speed-up, labelled in the page's language: the lab's --speedup (saved
        # as every twin's at start).
        assert page.inner_text('label[for="settings-twin-twin_speedup"]') == case["speedup"]
        assert page.input_value("#settings-twin-twin_speedup") == f"{settings_lab.speedup:g}"
        # Out of range: refused beside the field, in the page's language, nothing sent.
        page.fill(field, "5")
        form.locator("button[type=submit]").click()
        page.wait_for_selector(f"{field}[aria-invalid=true]")
        assert page.inner_text("#settings-twin-error").startswith(case["range"])
        assert int(form.get_attribute("data-version") or "0") == version
        assert serious_violations(page) == []
        page.fill(field, case["typed"])
        form.locator("button[type=submit]").click()
        page.wait_for_function(
            "v => Number(document.querySelector('[data-settings=\"twin\"] form')"
            "?.dataset.version) > v",
            arg=version,
        )
        assert page.input_value(field) == case["typed"]
        assert "tess" in page.inner_text('[data-settings="twin"]')
        assert ("rig.settings", "twin") in audited(page, "tess")
        page.screenshot(path=str(artifacts / f"settings-{language}.png"), full_page=True)

        # The student's rig page says how long a turn now lasts, and under the rig's name how
        # fast the twin runs (the lab's --speedup) with the turn (issue #24).
        own = student.new_page()
        own.goto(f"{settings_lab.url}/#/rig/twin")
        own.wait_for_function(
            "text => document.querySelector('[data-field=\"turnLength\"]')?.textContent === text",
            arg=case["shown"],
        )
        assert settings_lab.speedup == 200.0  # the pace the sentence states
        assert own.inner_text('[data-testid="rig-pace"]') == case["pace"]
        assert serious_violations(own) == []
    finally:
        student.close()
        teacher.close()


NAMES = {
    "pt-BR": {"locale": "pt-BR", "saved": "Salvo: os alunos da disciplina podem usar twin."},
    "en": {"locale": "en-GB", "saved": "Saved: the course's students may use twin."},
}


@pytest.mark.parametrize("language", list(NAMES))
def test_people_are_shown_by_name_and_a_teacher_chooses_a_courses_rigs(
    language: str, browser: Any, settings_lab: LabServer, artifacts: Path
) -> None:
    case = NAMES[language]
    suffix = language.lower().replace("-", "")
    teacher = _login(browser, settings_lab, "tess", case["locale"])
    student = _login(browser, settings_lab, "sam", case["locale"])
    try:
        page = teacher.new_page()
        page.goto(f"{settings_lab.url}/#/courses")
        page.wait_for_selector("#course-form")
        page.fill("#course-name", f"fis-{suffix}")
        page.fill("#course-title", "Física")
        page.click("#course-form button[type=submit]")
        page.wait_for_selector("#course-code")
        # A class list names the student: his display name from now on.
        roster = "username,display_name\nsam,Samuel Brandão\n".encode()
        page.set_input_files(
            "#roster-file", files=[{"name": "l.csv", "mimeType": "text/csv", "buffer": roster}]
        )
        page.click("#roster-upload")
        page.wait_for_selector("#roster-summary")
        # The course's rigs: the twin alone.
        page.check("#course-rig-twin")
        page.click("#course-rigs-save")
        page.wait_for_function(
            "text => document.querySelector('#course-rigs-result')?.textContent === text",
            arg=case["saved"],
        )
        assert serious_violations(page) == []
        page.screenshot(path=str(artifacts / f"course-rigs-{suffix}.png"), full_page=True)
        course = f"fis-{suffix}"
        made = {("course.created", course), ("course.roster", course), ("course.rigs", course)}
        assert made <= audited(page, "tess")

        own = student.new_page()
        own.goto(f"{settings_lab.url}/#/rig/twin")
        own.click("[data-action=ask]")
        own.wait_for_selector("[data-testid=access-role][data-role=controller]")
        own.wait_for_function(
            "() => document.querySelector('[data-field=\"controller\"]')?.textContent"
            " === 'Samuel Brandão'"
        )
        # The teacher sees the controller by name, with the login name actions take.
        page.goto(f"{settings_lab.url}/#/teacher")
        page.wait_for_function(
            '() => document.querySelector(\'[data-rig="twin"] [data-field="controller"]\')'
            "?.textContent === 'Samuel Brandão (sam)'"
        )
        assert "Samuel Brandão (sam)" in own.inner_text("#who-name")
        own.click("[data-action=release]")
        own.wait_for_selector("[data-testid=access-role][data-role=watcher]")
    finally:
        student.close()
        teacher.close()
