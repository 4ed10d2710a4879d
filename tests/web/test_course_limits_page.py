"""A course's limits in the browser (#10 item 3): the course page's form, in two languages.

A lab of its own (one twin, a technician's cap on the turn limit): the teacher
of a course sees the rule, ticks "set for this course" for the turn limit, a
value out of range is refused beside its field, a saved value is the one the
API returns, and the page passes axe with the form.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .axe import serious_violations
from .conftest import LabServer

pytestmark = pytest.mark.browser

CONFIG = """\
title = "ThermoLab course limits"

[[rigs]]
id = "twin"
title = "Digital twin of the paper's box"
spec = "sim"
caps = { control_time_limit = 3600 }
"""

CASES = {
    "en": {"locale": "en-GB", "heading": "Limits of this course", "rule": "booked slots"},
    "es": {"locale": "es-ES", "heading": "Límites de este curso", "rule": "horarios reservados"},
}


@pytest.fixture(scope="module")
def limits_lab(
    tmp_path_factory: pytest.TempPathFactory, browser: Any, start_lab: Any
) -> Iterator[LabServer]:
    with start_lab(tmp_path_factory.mktemp("limits-lab"), {"tess": "teacher"}, config=CONFIG) as s:
        yield s


def _login(browser: Any, lab: LabServer, user: str, locale: str) -> Any:
    context = browser.new_context(locale=locale, bypass_csp=True)
    page = context.new_page()
    page.goto(f"{lab.url}/")
    page.fill("#login-username", user)
    page.fill("#login-password", lab.password(user))
    page.click("form button[type=submit]")
    page.wait_for_selector("#nav:not([hidden])")
    page.close()
    return context


def _api(page: Any, method: str, path: str, body: object = None) -> Any:
    return page.evaluate(
        """async ([method, path, body]) => {
            const init = {method, headers: {"Content-Type": "application/json"}};
            if (body !== null) init.body = JSON.stringify(body);
            const res = await fetch(path, init);
            return {status: res.status, body: await res.json()};
        }""",
        [method, path, body],
    )


@pytest.mark.parametrize("language", list(CASES))
def test_the_teacher_of_a_course_sets_its_turn_limit_on_the_course_page(
    language: str, browser: Any, limits_lab: LabServer, artifacts: Path
) -> None:
    case = CASES[language]
    teacher = _login(browser, limits_lab, "tess", case["locale"])
    field = "#course-limit-control_time_limit"
    name = f"lim-{language}"
    try:
        page = teacher.new_page()
        page.goto(f"{limits_lab.url}/#/courses")
        made = _api(page, "POST", "/api/courses", {"name": name, "title": f"Limits {language}"})
        assert made["status"] == 201, made
        page.goto(f"{limits_lab.url}/#/courses?course={name}")
        page.wait_for_selector(field)
        assert page.inner_text("#course-limits-heading") == case["heading"]
        assert case["rule"] in page.inner_text("#course-limits-rule")
        # Unticked: the rig's value applies, the field is off.
        assert page.is_disabled(field)
        form = page.locator("#course-limits")
        page.check("#course-limit-control_time_limit-own")
        page.fill(field, "5")
        page.click("#course-limits-save")
        page.wait_for_selector(f"{field}[aria-invalid=true]")
        assert page.inner_text("#course-limits-error") != ""
        assert form.get_attribute("data-version") == "0"
        assert serious_violations(page) == []
        page.fill(field, "900")
        page.click("#course-limits-save")
        page.wait_for_function(
            "() => document.querySelector('#course-limits')?.dataset.version === '1'"
        )
        saved = _api(page, "GET", f"/api/courses/{name}/settings")
        by_name = {s["name"]: s for s in saved["body"]["settings"]}
        assert (by_name["control_time_limit"]["value"], by_name["idle_limit"]["overridden"]) == (
            900.0,
            False,
        )
        assert page.input_value(field) == "900"
        assert serious_violations(page) == []
        page.screenshot(path=str(artifacts / f"course-limits-{language}.png"), full_page=True)
    finally:
        teacher.close()
