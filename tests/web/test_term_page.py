"""The end of a term in the browser (#26 item 5), in Brazilian Portuguese.

A teacher copies a course to the next term by choosing the new term's first
day, closes it on its page (it then refuses changes with the catalogue's
sentence; its bookings to come are cancelled, which is why the copy comes
first here, the term's one class being still ahead), and finds the copy's
assignment among the assignments as a draft ("rascunho") that the students do
not see until it is published.
"""

from __future__ import annotations

from typing import Any

import pytest

from .axe import serious_violations
from .conftest import audited

pytestmark = pytest.mark.browser

# The old term's one class and deadline, and the new term's first day: 182 days
# (26 weeks) later, so the slot keeps its weekday and hour.
SLOT = {"startsAt": "2027-03-01T05:00:00+00:00", "endsAt": "2027-03-01T06:00:00+00:00"}
DEADLINE = "2027-03-08T12:00:00+00:00"
NEXT_TERM = "2027-08-30"

_POST = """async ([url, body]) => {
  const r = await fetch(url, {method: "POST", headers: {"Content-Type": "application/json",
    Accept: "application/json"}, body: JSON.stringify(body)});
  return [r.status, await r.text()];
}"""
_GET = """async (url) => (await fetch(url, {headers: {Accept: "application/json"}})).json()"""


def test_a_teacher_copies_a_course_to_the_next_term_and_closes_it_in_portuguese(
    logged_in: Any, lab: Any
) -> None:
    course, copy = "term-old", "term-new"
    context = logged_in("tess", locale="pt-BR", bypass_csp=True)
    try:
        page = context.new_page()
        page.goto(f"{lab.url}/#/courses")
        page.wait_for_selector("#course-form")
        page.fill("#course-name", course)
        page.fill("#course-title", "Controle I 2027/1")
        page.click("#course-form button[type=submit]")
        page.wait_for_selector("#term")
        assignment = {
            "title": "Resposta ao degrau",
            "rig": "twin-lang",
            "methods": ["lsm"],
            "deadline": DEADLINE,
        }
        status, text = page.evaluate(_POST, [f"/api/courses/{course}/assignments", assignment])
        assert status == 201, text
        booking = {"course": course, "rigs": ["twin-lang"], "note": "turma A", **SLOT}
        status, text = page.evaluate(_POST, ["/api/bookings", booking])
        assert status == 201, text

        # Copy it to the next term first: a close cancels the bookings still to come.
        page.fill("#copy-name", copy)
        page.fill("#copy-title", "Controle I 2027/2")
        page.fill("#copy-starts", NEXT_TERM)
        page.click("#copy-submit")
        page.wait_for_selector("#copy-summary")
        summary = page.inner_text("#copy-summary")
        assert summary.startswith(
            "Copiada. Atividades em rascunho: 1. Reservas: 1. Dias deslocados: 182."
        )
        assert page.inner_text("#copy-link") == "Controle I 2027/2"

        # Close it: two steps (the warning says its bookings to come are cancelled), then the
        # page says when and by whom, in Portuguese.
        assert page.inner_text("#term h3") == "Fim do semestre"
        assert page.inner_text("#term-state") == "A disciplina está aberta."
        page.click("#term-close")
        assert "as reservas da disciplina que ainda não começaram são canceladas" in (
            page.inner_text("#term-result")
        )
        page.click("#term-close-confirm")
        page.wait_for_selector('#term-state[data-closed="true"]')
        state = page.inner_text("#term-state")
        assert state.startswith("Encerrada em ")
        assert "por tess: pode ser consultada e exportada, mas não alterada." in state
        assert page.is_hidden("#term-close")
        # Its class to come was cancelled, freeing the rig; the copy's stays.
        window = "from=2027-02-01T00:00:00Z&to=2027-04-01T00:00:00Z"
        assert page.evaluate(_GET, f"/api/bookings?{window}") == []
        window = "from=2027-08-01T00:00:00Z&to=2027-10-01T00:00:00Z"
        assert [b["course"] for b in page.evaluate(_GET, f"/api/bookings?{window}")] == [copy]
        # A change is refused with the catalogue's sentence (409 course_closed).
        page.click("#course-rotate")
        page.wait_for_function(
            "() => document.querySelector('#roster-report').textContent.length > 0"
        )
        assert page.inner_text("#roster-report") == (
            "Esta disciplina está encerrada: pode ser consultada, mas não alterada."
        )

        assert {("course.closed", course), ("course.copied", copy)} <= audited(page, "tess")
        page.wait_for_selector(f'#course-list li[data-course="{course}"]')
        page.reload()
        closed = page.locator(f'#course-list li[data-course="{course}"] [data-closed]')
        closed.wait_for()
        assert closed.inner_text() == "encerrada"
        assert serious_violations(page) == []

        # The copy's assignment is a draft, its deadline moved by the same 182 days.
        page.goto(f"{lab.url}/#/assignments")
        page.wait_for_selector("#assign-list [data-draft]")
        drafts = page.locator("#assign-list li", has=page.locator("[data-draft]"))
        assert drafts.count() == 1
        item = drafts.first.inner_text()
        assert "Resposta ao degrau" in item
        assert "rascunho" in item
        assert "Controle I 2027/2" in item
        assert "06/09/2027" in item  # 8 March + 182 days, as a Brazilian reads a date
        drafts.first.locator("a").click()
        page.wait_for_selector("#assign-draft")
        assert page.inner_text("#assign-publish") == "Publicar"
        assert "os alunos da disciplina não o veem" in page.inner_text("#assign-draft")
    finally:
        context.close()


PRIVACY = {
    "pt-BR": ("Privacidade: o que o laboratório guarda sobre você", "Até que um administrador"),
    "en": ("Privacy: what the lab keeps about you", "Until an administrator removes it."),
    "es": ("Privacidad: lo que el laboratorio guarda sobre usted", "Hasta que un administrador"),
}
# The test lab sets no retention period: the page says nothing goes automatically.
NO_RETENTION = {
    "pt-BR": "Nada é removido automaticamente",
    "en": "Nothing is removed automatically",
    "es": "Nada se elimina automáticamente",
}


@pytest.mark.parametrize("language", list(PRIVACY))
def test_the_privacy_page_is_reached_from_the_login_page_in_each_language(
    language: str, browser: Any, lab: Any
) -> None:
    heading, retention = PRIVACY[language]
    context = browser.new_context(locale=language, bypass_csp=True)
    try:
        page = context.new_page()
        page.goto(f"{lab.url}/")
        page.wait_for_selector("#login-privacy")
        assert page.inner_text("#login-privacy") == heading
        page.click("#login-privacy")
        page.wait_for_selector("#privacy")
        assert page.inner_text("#privacy h1") == heading
        assert page.locator("#privacy-kept li").count() == 6
        assert page.inner_text("#privacy-retention").startswith(retention)
        page.wait_for_function("document.querySelector('#privacy-automatic')?.textContent")
        assert page.inner_text("#privacy-automatic").startswith(NO_RETENTION[language])
        assert page.is_visible("#privacy-login")  # not logged in: log in to download
        if language != "en":
            assert "account" not in page.inner_text("#privacy").lower()
        assert serious_violations(page) == []
    finally:
        context.close()
