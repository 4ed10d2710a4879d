"""Courses in the browser (#10): a teacher uploads a class list, a student enrols and logs in.

Run in Brazilian Portuguese and English: the page speaks the browser's
language, a malformed list is reported line by line in it, the new students'
one-time passwords are shown once and force a new password at the first
login, and a student who enrols with the course's code is logged in and can
log in again. The teacher adds a teaching assistant by login name, shown in
the roster as one; the audit log has it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from .axe import serious_violations
from .conftest import audited

pytestmark = pytest.mark.browser

WORDS = {
    "pt-BR": {
        "locale": "pt-BR",
        "courses": "Disciplinas",
        "line": "Linha 3: o arquivo não é texto em UTF-8 nem em Windows-1252 (byte 3 da linha)",
        "rigs": "Bancadas",
        "read": "Lido como Windows-1252.",
        "assistant": "monitor",
    },
    "en": {
        "locale": "en-GB",
        "courses": "Courses",
        "line": "Line 3: the file is not text in UTF-8 or Windows-1252 (byte 3 of the line)",
        "rigs": "Rigs",
        "read": "Read as Windows-1252.",
        "assistant": "teaching assistant",
    },
}


@pytest.mark.parametrize("language", list(WORDS))
def test_a_teacher_uploads_a_class_list_and_a_student_enrols_with_the_code(
    language: str, browser: Any, logged_in: Any, lab: Any, artifacts: Path
) -> None:
    words = WORDS[language]
    suffix = language.lower().replace("-", "")
    course = f"ctrl-{suffix}"
    teacher = logged_in("tess", locale=words["locale"], bypass_csp=True)
    student = browser.new_context(locale=words["locale"], bypass_csp=True)
    try:
        page = teacher.new_page()
        page.goto(f"{lab.url}/#/courses")
        page.wait_for_selector("#course-form")
        assert page.inner_text("h1") == words["courses"]
        page.fill("#course-name", course)
        page.fill("#course-title", "Controle I")
        page.click("#course-form button[type=submit]")
        page.wait_for_selector("#course-code")
        code = page.inner_text("#course-code")
        assert len(code) == 10

        # A list that is not text on line 3: every bad line reported in the page's
        # language, nobody added.
        bad = b"username,display_name\nana.m,Ana\nJo\x81o,Jo\x81o\n"
        page.set_input_files("#roster-file", files=[_csv("bad.csv", bad)])
        page.click("#roster-upload")
        page.wait_for_selector("#roster-errors li")
        assert page.inner_text("#roster-errors li").startswith(words["line"])
        assert page.locator("tr[data-member]").count() == 1  # the teacher alone

        first, second = f"joao.{suffix}", f"maria.{suffix}"
        # A Brazilian spreadsheet's own CSV: Portuguese headings, Windows-1252.
        good = f"Matrícula;Nome completo\nJoão.{suffix};João Gonçalves\n{second};Maria Álvares\n"
        page.set_input_files("#roster-file", files=[_csv("turma.csv", good.encode("cp1252"))])
        page.click("#roster-upload")
        page.wait_for_selector("#roster-passwords")
        cells = page.locator("#roster-passwords tbody tr").all_inner_texts()
        one_time = dict(cell.split("\t") for cell in cells)
        assert sorted(one_time) == [first, second]
        assert page.inner_text("#roster-encoding") == words["read"]
        page.wait_for_selector(f'tr[data-member="{first}"]')
        assert "João Gonçalves" in page.inner_text(f'tr[data-member="{first}"]')
        assert serious_violations(page) == []
        page.screenshot(path=str(artifacts / f"courses-{suffix}.png"), full_page=True)

        # A teaching assistant, added by login name (an account the administrator made).
        helper = f"tutor.{suffix}"
        account = {"username": helper, "password": "a long secret for the tutor", "role": "student"}
        status = page.evaluate(
            """async (body) => (await fetch("/api/users", {
                 method: "POST",
                 headers: {"Content-Type": "application/json"},
                 body: JSON.stringify(body),
               })).status""",
            account,
        )
        assert status == 201
        page.fill("#assistant-name", helper)
        page.click("#assistant-add")
        row = page.locator(f'tr[data-member="{helper}"]')
        row.wait_for()
        assert words["assistant"] in row.inner_text()
        assert ("course.assistant_added", course) in audited(page, "tess")

        # A student enrols with the code from the login page and is logged in.
        own = student.new_page()
        own.goto(f"{lab.url}/")
        own.click("#login-enrol")
        own.wait_for_selector("#enrol-code")
        assert serious_violations(own) == []
        user = f"bia.{suffix}"
        own.fill("#enrol-code", code)
        own.fill("#enrol-username", user)
        own.fill("#enrol-name", "Beatriz Gonçalves")
        own.fill("#enrol-password", "a long secret for bia")
        own.click("form button[type=submit]")
        own.wait_for_selector("#nav:not([hidden])")
        assert user in own.inner_text("#who-name")
        # ... and logs in again with the password she chose.
        own.click("#logout")
        own.wait_for_selector("#login-username")
        own.fill("#login-username", user.upper())
        own.fill("#login-password", "a long secret for bia")
        own.click("form button[type=submit]")
        own.wait_for_selector("#nav:not([hidden])")
        assert own.inner_text("h1") == words["rigs"]

        # A class-list student's one-time password leads to "choose a new password" first.
        own.click("#logout")
        own.wait_for_selector("#login-username")
        own.fill("#login-username", first)
        own.fill("#login-password", one_time[first])
        own.click("form button[type=submit]")
        own.wait_for_selector("#password-new")
        own.fill("#password-current", one_time[first])
        own.fill("#password-new", "joao's own long secret")
        own.click("form button[type=submit]")
        own.wait_for_selector(".rig-card, #main h1:not(:empty)")
        own.wait_for_function("() => !location.hash.includes('password')")
        page.reload()
        page.wait_for_selector(f'tr[data-member="{first}"]')
        assert page.locator(f'tr[data-member="{user}"]').count() == 1
    finally:
        student.close()
        teacher.close()


def _csv(name: str, data: bytes) -> dict[str, Any]:
    return {"name": name, "mimeType": "text/csv", "buffer": data}
